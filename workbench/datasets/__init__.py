"""Datasets: the shared :class:`Dataset` type and the loaders."""

from .base import Dataset, Hamiltonian
from .google_5q import DataUnavailableError, load_google_5q

__all__ = ["Dataset", "Hamiltonian", "DataUnavailableError", "load_google_5q"]
