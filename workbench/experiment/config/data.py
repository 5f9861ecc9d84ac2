"""``[data]``: where a config's data come from.

:class:`DataConfig`, with the Hamiltonian's columns in :class:`HamiltonianData`; ``source``
names a loader of the data-source registry (:mod:`workbench.datasets.sources`).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from ...datasets import DatasetError, get_source, source_names
from ...hamiltonian import make_graph
from .schema import Section, Seed

__all__ = ["DataConfig", "HamiltonianData"]


class HamiltonianData(Section):
    """``[data.hamiltonian]``: the Hamiltonian's columns.

    The control model's Hamiltonian ``H`` per row, for a CSV of your own: its N diagonal
    entries and one coupling per edge of the coupling graph.

    Parameters
    ----------
    onsite : list of str
        The N columns of ``H``'s diagonal, one per site.
    couplings : list of str
        The coupling columns, one per edge of the coupling graph, in edge order.
    sign : {-1, 1}, default=-1
        The prior is the ascending eigenvalues of ``sign * H``.
    topology : {"chain", "ring", "grid"}, default="chain"
        The coupling graph: "chain" (N - 1 couplings ``(i, i+1)``), "ring", or "grid" (with
        ``shape``).
    shape : list of int, default=None
        A grid's ``[rows, cols]``.
    edges : list of list of int, default=None
        An explicit coupling graph instead of ``topology``: 0-based site pairs, one per
        coupling column.
    qubit_features : list of str, default=None
        The columns among ``[data] features`` that act on each site, in site order (e.g.
        bias voltages).
    coupler_features : list of str, default=None
        The columns among ``[data] features`` that act on each coupling, in edge order.
    """

    onsite: list[str]
    couplings: list[str]
    sign: Literal[-1, 1] = -1
    topology: Literal["chain", "ring", "grid"] = "chain"
    shape: list[int] | None = None
    edges: list[list[int]] | None = None
    qubit_features: list[str] | None = None
    coupler_features: list[str] | None = None

    @model_validator(mode="after")
    def _graph(self) -> HamiltonianData:
        if self.shape is not None and self.topology != "grid":
            raise ValueError(f"shape applies to topology = \"grid\" only (topology is "
                             f"{self.topology!r})")
        if self.edges is not None and self.topology != "chain":
            raise ValueError("give either topology (with shape) or edges, not both")
        try:
            graph = make_graph(len(self.onsite), self.topology,
                               None if self.shape is None else tuple(self.shape), self.edges)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"coupling graph: {exc}") from None
        if len(self.couplings) != graph.n_edges:
            raise ValueError(f"couplings: the {graph.topology} graph of {len(self.onsite)} "
                             f"sites has {graph.n_edges} edges, got {len(self.couplings)} "
                             f"column(s)")
        return self


class DataConfig(Section):
    """``[data]``: where the data come from, and which columns and rows are which.

    ``source = "google_5q"`` (optional ``data_dir``), ``source = "ibm_gates"``
    (optional ``data_dir``, ``split = "time"`` or ``"devices"`` with ``split_seed``), or a CSV
    of your own (``csv``, one ``prior`` column per ``targets`` column, ``features``, either
    ``test_fraction`` or ``split_column``, optionally a ``group_column`` or an
    ``order_column`` that the CV folds follow, the targets' ``unit`` and the prior's name,
    ``prior_label``). Paths are
    relative to the config file.

    Parameters
    ----------
    source : str, default="google_5q"
        The data source, a name in the data-source registry
        (:data:`workbench.datasets.SOURCES`): ``"google_5q"``, ``"ibm_gates"``, ``"csv"``
        (implied by ``csv``) or one added with :func:`~workbench.datasets.register_source`.
    split : {"time", "devices"}, default=None
        ``ibm_gates``' split: ``"time"`` (``None`` too) tests on the snapshots from 2025 on,
        ``"devices"`` on 30% of the devices held out at random. A CSV's ``"time"``: the
        test rows are the latest ``test_fraction`` of the rows by ``order_column``.
    data_dir : str, default=None
        Where a benchmark's files are (``None``: the loader's own place, downloading them
        when missing).
    csv : str, default=None
        A CSV of your own, one experiment per row.
    prior : list of str, default=None
        The CSV's prior columns: ``prior[j]`` is the scientific model's prediction of
        ``targets[j]``. Every family but one that computes the prior itself (``parametric``:
        the user's model is the prior) needs them.
    targets : list of str, default=None
        The CSV's target columns, the measured values.
    features : list of str, default=[]
        The CSV's input columns (e.g. control settings).
    test_fraction : float, default=None
        A seeded random share of the CSV's rows held out as the test rows.
    split_column : str, default=None
        Instead, a column holding ``train`` or ``test`` per row.
    split_seed : int, default=0
        Seeds the random split (``test_fraction``; ``ibm_gates``' ``"devices"``).
    group_column : str, default=None
        A column holding each row's group (e.g. its device): CV folds keep a group's rows
        together (``[selection] groups``).
    order_column : str, default=None
        A column holding each row's place in time: dates or datetimes (``2024-03-01``,
        ``2024-03-01T09:30:00Z``) or numbers (run numbers, epochs; or any number the rows
        are ordered by, e.g. the direction the test rows extrapolate in). Every CV fold then
        chains forward (scikit-learn's ``TimeSeriesSplit``): it trains on the rows before
        the ones it holds out, and rows of one value stay on one side. Not a feature unless
        named in ``features`` too; not with ``group_column``.
    unit : str, default=None
        The targets' unit (e.g. ``"meV"``) that figures and summaries show.
    prior_label : str, default=None
        What the figures call the prior columns' model (e.g. ``"mass formula"``); ``None``:
        ``"prior"``. The benchmarks name theirs (``"control program"``, ``"coherence
        limit"``).
    hamiltonian : HamiltonianData, default=None
        ``[data.hamiltonian]``: the Hamiltonian's columns, for the physics-aware families.
    """

    source: str = "google_5q"
    split: Literal["time", "devices"] | None = None
    data_dir: str | None = None
    csv: str | None = None
    prior: list[str] | None = None
    targets: list[str] | None = None
    features: list[str] = []
    test_fraction: float | None = Field(default=None, gt=0, lt=1)
    split_column: str | None = None
    split_seed: int = Seed()
    group_column: str | None = None
    order_column: str | None = None
    unit: str | None = None
    prior_label: str | None = Field(default=None, min_length=1)
    hamiltonian: HamiltonianData | None = None

    @field_validator("source")
    @classmethod
    def _registered(cls, name: str) -> str:
        try:
            get_source(name)  # a plug-in's name too (entry points are read on a miss)
        except DatasetError:
            names = source_names()
            valid = ", ".join(repr(n) for n in names[:-1]) + f" or {names[-1]!r}"
            raise PydanticCustomError("unknown_source", "unknown data source; valid: {valid}",
                                      {"valid": valid}) from None
        return name

    @model_validator(mode="before")
    @classmethod
    def _csv_source(cls, data: Any) -> Any:
        if isinstance(data, dict) and "csv" in data and "source" not in data:
            data = {**data, "source": "csv"}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> DataConfig:
        csv_keys = sorted(k for k in ("csv", "prior", "targets", "test_fraction",
                                      "split_column", "group_column", "order_column",
                                      "hamiltonian", "unit", "prior_label")
                          if getattr(self, k) is not None) + (["features"] if self.features
                                                              else [])
        if self.source != "csv":
            if csv_keys:
                raise ValueError(f"{csv_keys} apply to source = \"csv\" only")
            if self.split is not None and self.source != "ibm_gates":
                raise ValueError("'split' applies to source = \"ibm_gates\" only")
            return self
        if self.split == "devices":
            raise ValueError("split = \"devices\" applies to source = \"ibm_gates\" only (a "
                             "CSV's split: test_fraction, split_column, or split = \"time\")")
        if self.split == "time" and (self.order_column is None or self.test_fraction is None):
            raise ValueError("a CSV's split = \"time\" tests on the latest test_fraction of "
                             "the rows by order_column: give both")
        if self.order_column is not None and self.group_column is not None:
            raise ValueError("give group_column or order_column, not both: the CV folds "
                             "either keep groups whole or chain forward in time")
        for key in ("csv", "targets"):  # "prior": the family's check_data
            if getattr(self, key) is None:
                raise ValueError(f"source = \"csv\" needs {key!r}")
        assert self.targets is not None  # checked just above
        if self.prior is not None and len(self.prior) != len(self.targets):
            raise ValueError(f"{len(self.prior)} prior column(s) for {len(self.targets)} "
                             f"target(s): give one prior column per target")
        if (self.test_fraction is None) == (self.split_column is None):
            raise ValueError("give exactly one of test_fraction or split_column")
        return self
