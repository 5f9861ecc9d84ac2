"""Datasets: the shared :class:`Dataset` type, the loaders and the data-source registry
(:mod:`.sources`: the names ``[data] source`` takes)."""

from . import google_5q, ibm_gates
from .base import Dataset, Hamiltonian
from .csv import DatasetError, load_csv_dataset, read_csv_cells, read_numeric_columns, read_once
from .google_5q import load_google_5q
from .ibm_gates import load_ibm_gates
from .ibm_qubits import load_ibm_qubits
from .sources import (
    SOURCE_ENTRY_POINT_GROUP,
    SOURCES,
    DataSource,
    discover_sources,
    get_source,
    load_source,
    register_source,
    source_names,
)
from .wheel import DataUnavailableError, WheelData

#: The real benchmarks' sources (``[data] source``) and the wheels their files come from.
BENCHMARKS: dict[str, WheelData] = {"google_5q": google_5q.WHEEL, "ibm_gates": ibm_gates.WHEEL}

__all__ = ["BENCHMARKS", "SOURCES", "SOURCE_ENTRY_POINT_GROUP", "DataSource",
           "DataUnavailableError", "Dataset", "DatasetError", "Hamiltonian", "discover_sources",
           "get_source", "load_csv_dataset", "load_google_5q", "load_ibm_gates",
           "load_ibm_qubits", "load_source", "read_csv_cells", "read_numeric_columns",
           "read_once", "register_source", "source_names"]
