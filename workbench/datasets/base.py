"""The dataset type shared by every loader."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..hamiltonian import CouplingGraph


@dataclass(frozen=True)
class Hamiltonian:
    """Per-example parameters of a device's control-model Hamiltonian.

    One row per example, aligned with the dataset's rows. The prior is the ascending
    eigenvalues of ``sign * H``.

    Parameters
    ----------
    onsite : DataFrame
        The N diagonal entries (qubit frequencies, MHz).
    couplings : DataFrame
        One coupling per edge of the coupling graph.
    sign : int, default=-1
        The sign of ``H`` whose eigenvalues are the prior.
    qubit_features : tuple of str, default=None
        N names of the dataset features that act on each site (e.g. bias voltages), in site
        order, for physics-aware covariates.
    coupler_features : tuple of str, default=None
        The same for each coupling, in edge order.
    edges : tuple of (int, int), default=None
        The graph's site pairs (0-based, one per coupling column, in order); ``None``: the
        nearest-neighbour chain.
    """

    onsite: pd.DataFrame
    couplings: pd.DataFrame
    sign: int = -1
    qubit_features: tuple[str, ...] | None = None
    coupler_features: tuple[str, ...] | None = None
    edges: tuple[tuple[int, int], ...] | None = None

    @property
    def graph(self) -> CouplingGraph:
        """The coupling graph (the chain when ``edges`` is None)."""
        n = self.onsite.shape[1]
        return CouplingGraph.chain(n) if self.edges is None else \
            CouplingGraph.from_edges(n, self.edges)

    @property
    def edge_list(self) -> list[list[int]] | None:
        """``edges`` as a list of [i, j] (the estimators' ``edges`` parameter), or None."""
        return None if self.edges is None else [list(e) for e in self.edges]


@dataclass(frozen=True)
class Dataset:
    """Features, one prior column per target, the targets and a train/test split.

    All frames share one row index.

    Parameters
    ----------
    name : str
        The data set's name.
    features : DataFrame
        The inputs.
    prior : DataFrame
        One prior column per target, in the targets' order.
    targets : DataFrame
        The measured targets.
    train_index, test_index : ndarray
        The index labels of the training and the test rows.
    hamiltonian : Hamiltonian, default=None
        The control model's Hamiltonian parameters per row, for the physics-aware models.
    groups : Series, default=None
        Each row's group (e.g. the device it was measured on): rows of one group share
        conditions a model must not learn from the test rows.
    unit : str, default=None
        The targets' (and priors') unit, as figures and summaries label it (e.g. ``"MHz"``);
        ``None``: no unit is shown.
    order : Series, default=None
        Each row's place in time (numbers, or datetimes; larger is later), e.g. the date a
        row was measured: CV folds follow it (forward-chaining), and it is no feature.
    prior_label : str, default="prior"
        What figures and tables call the prior (e.g. ``"control program"``, ``"coherence
        limit"``).
    """

    name: str
    features: pd.DataFrame
    prior: pd.DataFrame
    targets: pd.DataFrame
    train_index: np.ndarray
    test_index: np.ndarray
    hamiltonian: Hamiltonian | None = None
    groups: pd.Series | None = None
    unit: str | None = None
    order: pd.Series | None = None
    prior_label: str = "prior"

    @property
    def target_names(self) -> list[str]:
        """The targets' column names."""
        return [str(c) for c in self.targets.columns]

    @property
    def prior_names(self) -> list[str]:
        """The prior columns' names."""
        return [str(c) for c in self.prior.columns]

    @property
    def feature_names(self) -> list[str]:
        """The features' column names."""
        return [str(c) for c in self.features.columns]

    @property
    def X(self) -> pd.DataFrame:
        """Model inputs: the features followed by the prior columns."""
        return pd.concat([self.features, self.prior], axis=1)

    @property
    def X_physics(self) -> pd.DataFrame:
        """:attr:`X` followed by the control model's onsite and coupling columns."""
        if self.hamiltonian is None:
            raise ValueError(f"dataset {self.name!r} has no Hamiltonian parameters (for a CSV, "
                             "name them in [data.hamiltonian] onsite and couplings)")
        ham = self.hamiltonian
        return pd.concat([self.X, ham.onsite, ham.couplings], axis=1)

    def split(self, X: pd.DataFrame | None = None
              ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]:
        """``X_train, X_test, y_train, y_test`` for the dataset's split (of ``X``, default
        :attr:`X`).

        Parameters
        ----------
        X : pandas.DataFrame, default=None
            Inputs indexed as the dataset's rows (``None``: :attr:`X`).

        Returns
        -------
        X_train, X_test : pandas.DataFrame
            The inputs' training and test rows.
        y_train, y_test : pandas.DataFrame
            The targets' training and test rows.
        """
        X = self.X if X is None else X
        return (
            X.loc[self.train_index],
            X.loc[self.test_index],
            self.targets.loc[self.train_index],
            self.targets.loc[self.test_index],
        )
