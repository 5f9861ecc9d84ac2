"""Datasets: the shared :class:`Dataset` type and the loaders."""

from .base import Dataset, Hamiltonian
from .csv import DatasetError, load_csv_dataset
from .google_5q import DataUnavailableError, load_google_5q

__all__ = ["Dataset", "DatasetError", "DataUnavailableError", "Hamiltonian", "load_csv_dataset",
           "load_google_5q"]
