"""Simulated calibration data for coupled flux-tunable qubits (units: MHz, volts).

The device is a :class:`~workbench.hamiltonian.CouplingGraph`: a chain (default), a ring or a
2-D grid. A *control model* maps qubit biases ``V_q`` (N) and coupler biases ``V_c`` (one per
edge) to a tight-binding Hamiltonian: transmon frequencies ``f_i`` on the diagonal, couplings
``g_e`` between the qubits of each edge off it (built by :mod:`workbench.hamiltonian`, the
model's own builder). The prior is ``eigvalsh(sign * H_model)`` (sign = -1). The
*true device* departs from the model in named, switchable ways (:class:`Mismatch`); its
eigenvalues, plus noise and occasional misidentified peaks, are the measured targets.

The device seed (``device_seed``, ``workbench simulate --device-seed``) fixes the device
(control-model constants and every hidden mismatch draw: drift, crosstalk, kappa, Delta_c,
eta). :func:`simulate` measures random bias settings on it;
:func:`measure` measures settings the caller chooses (e.g. an active-learning loop) on the
same device, through the same physics.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ._io import atomic_write
from .hamiltonian import CouplingGraph, graph_spectrum, make_graph

__all__ = ["MECHANISMS", "Mismatch", "Simulation", "bias_columns", "measure", "simulate",
           "write_simulation"]

SIGN = -1
Q_RANGE, C_RANGE = (-0.015, 0.015), (0.10, 0.22)  # uniform bias ranges (V)
V_CAL = 0.16  # coupler bias at which the control model was calibrated (V)
#: mechanism name -> Mismatch field
MECHANISMS = {**{k: k for k in ("drift", "crosstalk", "coupler_nonlinearity",
                                 "coupler_frequency_shift", "next_nearest_coupling")},
              "noise": "noise_sd", "misidentified_peaks": "misidentified_rate"}


@dataclass(frozen=True)
class Mismatch:
    """How the true device departs from the control model; 0 switches a mechanism off.

    Parameters
    ----------
    drift : float, default=0.0
        Multiplier of per-element parameter offsets (1 = sd 1.5 MHz on f_max, 0.2 mV on the
        sweet spot V0, 0.3 % on the flux period, 3 % on g_max, 1 mV on the coupler midpoint).
    crosstalk : float, default=0.0
        Flux crosstalk fraction: qubit i feels about this fraction (times U(0.5, 1.5), random
        sign) of the bias of neighbouring qubits i±1 and of its adjacent couplers (coupler
        bias relative to the calibration point ``V_CAL``, whose constant part the model
        absorbed).
    coupler_nonlinearity : float, default=0.0
        In MHz: the true g gains ``kappa * ((V_c - 0.16) / 0.06)**2``, with ``abs(kappa)``
        about this.
    coupler_frequency_shift : float, default=0.0
        Dimensionless: each coupler pulls its two qubits down by ``this * g**2 / Delta_c``
        (``Delta_c`` about 1 GHz, a dispersive shift).
    next_nearest_coupling : float, default=0.0
        Parasitic couplings the control model lacks, between the sites of each parasitic
        pair (i, j) (chain or ring: next-nearest, grid: diagonal):
        ``H[i, j] = -this * eta_ij * mean over paths i-m-j of sqrt(abs(g_im * g_mj))``, with
        ``eta_ij`` drawn from U(0.5, 1.5).
    noise_sd : float, default=0.0
        Standard deviation of the Gaussian measurement noise on each measured eigenvalue
        (MHz).
    misidentified_rate : float, default=0.0
        Per-experiment probability that one eigenvalue is a wrong peak (shifted by 3 to
        10 MHz either way); at most 1.
    """

    drift: float = 0.0
    crosstalk: float = 0.0
    coupler_nonlinearity: float = 0.0
    coupler_frequency_shift: float = 0.0
    next_nearest_coupling: float = 0.0
    noise_sd: float = 0.0
    misidentified_rate: float = 0.0

    def __post_init__(self) -> None:
        """Check every size is a finite number >= 0 and the misidentified rate <= 1."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Mismatch.{f.name} must be a finite number >= 0, got {value!r}")
        if self.misidentified_rate > 1:
            raise ValueError(f"misidentified_rate must be <= 1, got {self.misidentified_rate}")

    @classmethod
    def none(cls) -> Mismatch:
        """Everything off: the true device is the control model."""
        return cls()

    @classmethod
    def default(cls) -> Mismatch:
        """Every mechanism on at realistic sizes (prior MAE ~1-2 MHz at N = 5)."""
        return cls(drift=0.6, crosstalk=0.006, coupler_nonlinearity=1.5,
                   coupler_frequency_shift=0.3, next_nearest_coupling=0.03, noise_sd=0.3,
                   misidentified_rate=0.02)

    @classmethod
    def only(cls, *names: str) -> Mismatch:
        """The named mechanisms at their default sizes, the others off.

        Parameters
        ----------
        *names : str
            Names of :data:`MECHANISMS`.

        Returns
        -------
        Mismatch
            The mismatch.

        Raises
        ------
        ValueError
            An unknown name, listing the valid ones.
        """
        unknown = [n for n in names if n not in MECHANISMS]
        if unknown:
            raise ValueError(f"unknown mismatch mechanism(s) {unknown}; valid names are: "
                             f"{', '.join(MECHANISMS)}")
        default = cls.default()
        return cls(**{MECHANISMS[n]: getattr(default, MECHANISMS[n]) for n in names})

    def to_dict(self) -> dict:
        """Write the sizes as JSON-ready data.

        Returns
        -------
        dict
            Each mechanism's field and size.
        """
        return dataclasses.asdict(self)


@dataclass
class Simulation:
    """Simulated experiments and everything injected to make them.

    Parameters
    ----------
    data : DataFrame
        One row per experiment: the biases, the control model's parameters and prior, the
        measured eigenvalues.
    truth : dict
        The device, the mismatch and its hidden draws, the seeds (JSON-ready)."""

    data: pd.DataFrame
    truth: dict


def transmon_frequency(v: np.ndarray | float, f_max: np.ndarray | float, v0: np.ndarray | float,
                       period: np.ndarray | float) -> np.ndarray:
    """Flux-tunable transmon: f = f_max sqrt(|cos(pi (V - V0) / period)|).

    Parameters
    ----------
    v : ndarray or float
        The bias voltage ``V``.
    f_max : ndarray or float
        The frequency at the sweet spot.
    v0 : ndarray or float
        The sweet spot's voltage ``V0``.
    period : ndarray or float
        The voltage of one flux quantum.

    Returns
    -------
    ndarray
        The frequency, broadcast over the arguments.
    """
    return f_max * np.sqrt(np.abs(np.cos(np.pi * (v - v0) / period)))


def coupler_coupling(v: np.ndarray | float, g_max: np.ndarray | float,
                     v_half: np.ndarray | float, width: np.ndarray | float) -> np.ndarray:
    """Tunable (gmon-like) coupler: g = -g_max / (1 + exp(-(V - V_half) / width)), monotone.

    Parameters
    ----------
    v : ndarray or float
        The coupler's bias voltage ``V``.
    g_max : ndarray or float
        The coupling's largest magnitude.
    v_half : ndarray or float
        The voltage of half the largest coupling ``V_half``.
    width : ndarray or float
        The voltage scale of the switch.

    Returns
    -------
    ndarray
        The coupling, broadcast over the arguments.
    """
    return -g_max / (1.0 + np.exp(-(v - v_half) / width))


def _eigenvalues(f: np.ndarray, g: np.ndarray, graph: CouplingGraph,
                 extra: np.ndarray | None = None,
                 pairs: Sequence[tuple[int, int]] = ()) -> np.ndarray:
    """Ascending eigenvalues of sign * H per row (the model's builder), with the couplings
    ``extra`` on the parasitic ``pairs`` added to the graph's edges."""
    if extra is not None and len(pairs):
        return graph_spectrum(f, np.hstack([g, extra]), graph.with_edges(pairs), SIGN,
                              jacobian=False)
    return graph_spectrum(f, g, graph, SIGN, jacobian=False)


def _device(rng: np.random.Generator, n: int, n_edges: int) -> dict[str, np.ndarray]:
    """Control-model constants of one device (so f ~ 5880-6025 MHz, g ~ -1..-70 MHz)."""
    return dict(f_max=rng.uniform(5995, 6025, n), v0=rng.uniform(-0.004, 0.004, n),
                period=rng.uniform(0.22, 0.26, n), g_max=rng.uniform(62, 75, n_edges),
                v_half=rng.uniform(0.165, 0.175, n_edges),
                width=rng.uniform(0.018, 0.022, n_edges))


def default_parasitic(graph: CouplingGraph) -> str:
    """Name the parasitic pairs the simulator injects by default.

    Parameters
    ----------
    graph : CouplingGraph
        The device's coupling graph.

    Returns
    -------
    str
        ``"diagonal"`` for a grid, else ``"next_nearest"``.
    """
    return "diagonal" if graph.topology == "grid" else "next_nearest"


@dataclass
class _Device:
    """One seeded device: graph, parasitic pairs, control model and the unit-size draws of
    every mismatch mechanism (scaled by a :class:`Mismatch` in :func:`_experiments`)."""

    graph: CouplingGraph
    pairs: list
    device_seed: int | None
    ctrl: dict
    z: dict
    xt: np.ndarray
    kappa: np.ndarray
    delta_c: np.ndarray
    eta: np.ndarray


def _build_device(n_sites: int | None, topology: str, shape: Any,
                  edges: Iterable[Sequence[int]] | None,
                  parasitic: str | Iterable[Sequence[int]] | None,
                  device_seed: int | None) -> tuple[_Device, np.random.Generator]:
    """The device of ``device_seed``, and the generator after its draws (simulate() draws
    on)."""
    if n_sites is not None and (int(n_sites) != n_sites or n_sites < 2):
        raise ValueError(f"n_sites must be an integer >= 2, got {n_sites!r}")
    graph = make_graph(None if n_sites is None else int(n_sites), topology, shape, edges)
    if isinstance(parasitic, str) or parasitic is None:
        pairs = graph.parasitic_edges(default_parasitic(graph) if parasitic is None
                                      else parasitic)
    else:
        pairs = list(graph.with_edges(parasitic).edges[graph.n_edges:])
    n, E = graph.n_sites, graph.n_edges
    rng = np.random.default_rng(device_seed)
    ctrl = _device(rng, n, E)
    # unit-size draws of every mechanism, scaled by the mismatch strengths in _experiments
    z = {k: rng.standard_normal(v.shape) for k, v in ctrl.items()}
    xt = rng.uniform(0.5, 1.5, (4, E)) * rng.choice([-1.0, 1.0], (4, E))
    kappa = rng.uniform(0.5, 1.5, E) * rng.choice([-1.0, 1.0], E)
    delta_c = rng.uniform(800, 1200, E)
    eta = rng.uniform(0.5, 1.5, len(pairs))
    device = _Device(graph, pairs, None if device_seed is None else int(device_seed), ctrl, z,
                     xt, kappa, delta_c, eta)
    return device, rng


def _readout_draws(rng: np.random.Generator, m: int, n: int) -> tuple:
    """Per-experiment noise and misidentified-peak draws of ``m`` experiments."""
    noise = rng.standard_normal((m, n))
    bad_u, bad_level = rng.random(m), rng.integers(0, n, m)
    bad_shift = rng.uniform(3, 10, m) * rng.choice([-1.0, 1.0], m)
    return noise, bad_u, bad_level, bad_shift


def _true_spectrum(dev: _Device, mm: Mismatch, vq: np.ndarray, vc: np.ndarray, ea: np.ndarray,
                   eb: np.ndarray) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """The true device at the biases ``vq`` and ``vc``: its constants (``true``), the
    crosstalk matrix ``xt``, the coupler pull's ``shift_coef`` and its eigenvalues ``e_true``
    (noise-free), every mechanism of ``mm`` applied to the control model of ``dev``."""
    graph, pairs, ctrl = dev.graph, dev.pairs, dev.ctrl
    m = len(vq)
    sd = dict(f_max=1.5, v0=2e-4, period=0.003, g_max=0.03, v_half=1e-3, width=0.02)
    rel = {"period", "g_max", "width"}
    true = {k: v * (1 + mm.drift * sd[k] * dev.z[k]) if k in rel
            else v + mm.drift * sd[k] * dev.z[k] for k, v in ctrl.items()}
    # rows of xt, edge e = (a, b): q_b <- q_a, q_a <- q_b, q_a <- c_e, q_b <- c_e
    xt = mm.crosstalk * dev.xt
    v_eff = vq.copy()
    v_eff_b = np.zeros_like(vq)
    np.add.at(v_eff_b.T, eb, (xt[0] * vq[:, ea] + xt[3] * (vc - V_CAL)).T)
    v_eff += v_eff_b
    v_eff_a = np.zeros_like(vq)
    np.add.at(v_eff_a.T, ea, (xt[1] * vq[:, eb] + xt[2] * (vc - V_CAL)).T)
    v_eff += v_eff_a
    f_true = transmon_frequency(v_eff, true["f_max"], true["v0"], true["period"])
    g_true = coupler_coupling(vc, true["g_max"], true["v_half"], true["width"])
    g_true = g_true + mm.coupler_nonlinearity * dev.kappa * ((vc - V_CAL) / 0.06) ** 2
    shift_coef = mm.coupler_frequency_shift / dev.delta_c  # per MHz, frequencies pulled down
    pull = g_true**2 * shift_coef
    pull_a, pull_b = np.zeros_like(f_true), np.zeros_like(f_true)
    np.add.at(pull_a.T, ea, pull.T)  # coupler e = (a, b) pulls qubits a and b
    np.add.at(pull_b.T, eb, pull.T)
    f_true -= pull_a
    f_true -= pull_b
    bridge = np.zeros((m, len(pairs)))
    for k, (i, j) in enumerate(pairs):
        paths = graph.paths2(i, j)
        bridge[:, k] = np.mean([np.sqrt(np.abs(g_true[:, a] * g_true[:, b])) for a, b in paths],
                               axis=0) if paths else 0.0
    nnn = -mm.next_nearest_coupling * dev.eta * bridge
    e_true = _eigenvalues(f_true, g_true, graph, nnn, pairs)
    return true, xt, shift_coef, e_true


def _mechanisms(dev: _Device, mm: Mismatch, true: dict, xt: np.ndarray, shift_coef: np.ndarray,
                edge_ab: list[tuple[int, int]], bad: np.ndarray, bad_level: np.ndarray,
                bad_shift: np.ndarray) -> dict:
    """The ``truth["mechanisms"]`` record: each mismatch as injected, with its formula."""
    ctrl = dev.ctrl
    return {
        "drift": {k: (np.asarray(true[k]) - ctrl[k]).tolist() for k in ctrl},
        "crosstalk": {  # [qubit row, qubit/coupler column (0-based), value]
            "qubit_from_qubit": [[b, a, float(xt[0, e])] for e, (a, b) in enumerate(edge_ab)]
            + [[a, b, float(xt[1, e])] for e, (a, b) in enumerate(edge_ab)],
            "qubit_from_coupler": [[a, e, float(xt[2, e])] for e, (a, b) in enumerate(edge_ab)]
            + [[b, e, float(xt[3, e])] for e, (a, b) in enumerate(edge_ab)],
            "formula": "V_eff = V_q + C_qq V_q + C_qc (V_c - 0.16)"},
        "coupler_nonlinearity": {"kappa_MHz": (mm.coupler_nonlinearity * dev.kappa).tolist(),
                                 "formula": "g += kappa ((V_c - 0.16) / 0.06)^2"},
        "coupler_frequency_shift": {
            "sign": -1, "coef_per_MHz": shift_coef.tolist(),
            "delta_c_MHz": dev.delta_c.tolist(),
            "formula": "f_a and f_b += sign * coef_e * g_e^2 (true g, edge e = (a, b))"},
        "next_nearest_coupling": {
            "pairs": [list(p) for p in dev.pairs],
            "eta": (mm.next_nearest_coupling * dev.eta).tolist(),
            "formula": "H[i, j] = -eta_ij mean over paths i-m-j of sqrt(|g_im g_mj|) "
                       "(true g; pairs are 0-based sites)"},
        "noise": {"sd_MHz": mm.noise_sd},
        "misidentified_peaks": {
            "rate": mm.misidentified_rate, "rows": bad.tolist(),
            "level": (bad_level[bad] + 1).tolist(), "shift_MHz": bad_shift[bad].tolist(),
            "note": "level k (1-based): the k-th ascending true eigenvalue + shift"},
    }


def _experiments(dev: _Device, mm: Mismatch, vq: np.ndarray, vc: np.ndarray, draws: tuple,
                 index: pd.Index | None = None) -> Simulation:
    """The prior and the true device's measured eigenvalues at the biases ``vq`` (m, N) and
    ``vc`` (m, E), with the :func:`_readout_draws` ``draws``; ``index`` labels the rows."""
    graph, ctrl = dev.graph, dev.ctrl
    noise, bad_u, bad_level, bad_shift = draws
    n, m, E = graph.n_sites, len(vq), graph.n_edges
    ea = np.array([e[0] for e in graph.edges], dtype=int)
    eb = np.array([e[1] for e in graph.edges], dtype=int)

    # control model and its prior
    f_model = transmon_frequency(vq, ctrl["f_max"], ctrl["v0"], ctrl["period"])
    g_model = coupler_coupling(vc, ctrl["g_max"], ctrl["v_half"], ctrl["width"])
    e_model = _eigenvalues(f_model, g_model, graph)

    true, xt, shift_coef, e_true = _true_spectrum(dev, mm, vq, vc, ea, eb)
    measured = e_true + mm.noise_sd * noise
    bad = np.flatnonzero(bad_u < mm.misidentified_rate)  # one wrong peak in these rows
    measured[bad, bad_level[bad]] += bad_shift[bad]
    measured.sort(axis=1)

    names = (bias_columns(n, E) + [f"model_f{k}" for k in range(1, n + 1)]
             + [f"model_g{k}" for k in range(1, E + 1)]
             + [f"model_E{k}" for k in range(1, n + 1)]
             + [f"measured_E{k}" for k in range(1, n + 1)])
    data = pd.DataFrame(np.hstack([vq, vc, f_model, g_model, e_model, measured]), columns=names,
                        index=index)

    edge_ab = list(zip(ea.tolist(), eb.tolist()))
    truth = {
        "n_sites": n, "n_experiments": m, "device_seed": dev.device_seed,
        "graph": graph.to_dict(),
        "sign": SIGN, "units": "MHz, V", "mismatch": mm.to_dict(),
        "voltage_ranges": {"qubit": list(Q_RANGE), "coupler": list(C_RANGE)},
        "device": {"control": {k: v.tolist() for k, v in ctrl.items()},
                   "true": {k: v.tolist() for k, v in true.items()}},
        "mechanisms": _mechanisms(dev, mm, true, xt, shift_coef, edge_ab, bad, bad_level,
                                  bad_shift),
    }
    return Simulation(data=data, truth=json.loads(json.dumps(truth)))


def bias_columns(n_sites: int, n_edges: int) -> list[str]:
    """The bias columns of a device: ``v_q1..v_qN`` then ``v_c1..v_cE``.

    Parameters
    ----------
    n_sites : int
        The qubits, N.
    n_edges : int
        The couplers, E.

    Returns
    -------
    list of str
        The column names.
    """
    return ([f"v_q{k}" for k in range(1, n_sites + 1)]
            + [f"v_c{k}" for k in range(1, n_edges + 1)])


def simulate(n_sites: int | None = 5, n_experiments: int = 136, *,
             device_seed: int | None = 0, mismatch: Mismatch | None = None,
             topology: str = "chain", shape: Any = None,
             edges: Iterable[Sequence[int]] | None = None,
             parasitic: str | Iterable[Sequence[int]] | None = None) -> Simulation:
    """Simulate ``n_experiments`` random bias settings of a device of ``n_sites`` sites.

    All random draws are made in a fixed order whatever the mismatch (the device first, then
    the voltages, uniform in Q_RANGE and C_RANGE, then noise and misidentified peaks), so the
    same ``device_seed`` gives the same device and voltages and only the switched-on
    mechanisms change the targets. :func:`measure` measures chosen settings on the same device.

    Parameters
    ----------
    n_sites : int or None, default=5
        The sites (a grid: ``None`` or rows * cols).
    n_experiments : int, default=136
        The bias settings drawn.
    device_seed : int or None, default=0
        Seeds every draw: the device, then its voltages and noise (``None``: fresh ones).
        Formerly ``seed``.
    mismatch : Mismatch, default=None
        How the true device departs from the control model (``None``: it does not).
    topology : {"chain", "ring", "grid"}, default="chain"
        The coupling graph's shape.
    shape : (int, int), default=None
        ``(rows, cols)`` of a grid.
    edges : iterable of (int, int), default=None
        An explicit list of coupled site pairs instead of a topology.
    parasitic : str or iterable of (int, int), default=None
        Where the next_nearest_coupling mismatch puts its parasitic couplings:
        ``"next_nearest"``, ``"diagonal"``, ``"none"`` or a list of site pairs (``None``:
        :func:`default_parasitic`).

    Returns
    -------
    Simulation
        The table (biases, control model, measured peaks) and the device's truth.
    """
    if int(n_experiments) != n_experiments or n_experiments < 1:
        raise ValueError(f"n_experiments must be an integer >= 1, got {n_experiments!r}")
    dev, rng = _build_device(n_sites, topology, shape, edges, parasitic, device_seed)
    n, m, E = dev.graph.n_sites, int(n_experiments), dev.graph.n_edges
    vq = rng.uniform(*Q_RANGE, (m, n))
    vc = rng.uniform(*C_RANGE, (m, E))
    return _experiments(dev, Mismatch.default() if mismatch is None else mismatch, vq, vc,
                        _readout_draws(rng, m, n))


def measure(settings: pd.DataFrame, *, device_seed: int | None = 0,
            mismatch: Mismatch | None = None, topology: str = "chain",
            n_sites: int | None = None, shape: Any = None,
            edges: Iterable[Sequence[int]] | None = None,
            parasitic: str | Iterable[Sequence[int]] | None = None,
            noise_seed: int | None = None) -> Simulation:
    """Measure the bias ``settings`` (rows of ``v_q1..v_qN``, ``v_c1..v_cE``; other columns
    are ignored) on the device :func:`simulate` makes with the same ``device_seed``,
    ``topology``, ``n_sites``, ``shape``, ``edges``, ``parasitic`` and ``mismatch``.

    Voltages outside Q_RANGE and C_RANGE are allowed. The rows come back in the order and
    with the index of ``settings``, in simulate()'s columns; ``truth`` is simulate()'s for
    this device with ``n_experiments`` the rows measured here and the misidentified rows
    (0-based positions) of this call.

    Parameters
    ----------
    settings : DataFrame
        The biases to measure.
    device_seed : int or None, default=0
        The device's seed (``None``: a fresh device and fresh noise). Formerly ``seed``.
    mismatch : Mismatch, default=None
        As in :func:`simulate`.
    topology, shape, edges, parasitic
        As in :func:`simulate`.
    n_sites : int, default=None
        The sites (``None`` with a chain or ring: the number of ``v_q`` columns).
    noise_seed : int, default=None
        Seeds the noise and the misidentified peaks; ``None``: a seed derived from
        ``device_seed`` and the settings' values (the same settings measure the same,
        different settings get independent noise).

    Returns
    -------
    Simulation
        The table (biases, control model, measured peaks) and the device's truth.

    Raises
    ------
    ValueError
        On a missing column, a non-numeric, NaN or infinite bias, or no rows.
    """
    if not isinstance(settings, pd.DataFrame):
        raise TypeError(f"settings must be a pandas DataFrame, got {type(settings).__name__}")
    if noise_seed is not None and (int(noise_seed) != noise_seed or noise_seed < 0):
        raise ValueError(f"noise_seed must be an integer >= 0, got {noise_seed!r}")
    if n_sites is None and edges is None and topology in ("chain", "ring"):
        n_sites = 0
        while f"v_q{n_sites + 1}" in settings.columns:
            n_sites += 1
        if n_sites < 2:
            raise ValueError(f"settings need the qubit bias columns v_q1, v_q2, ... (a "
                             f"{topology} of >= 2 sites); found {n_sites}")
    dev, _ = _build_device(n_sites, topology, shape, edges, parasitic, device_seed)
    n, E = dev.graph.n_sites, dev.graph.n_edges
    columns = bias_columns(n, E)
    missing = [c for c in columns if c not in settings.columns]
    if missing:
        listed = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8
                                           else "")
        raise ValueError(f"settings lack the bias column(s) {listed}: the device has {n} sites "
                         f"(v_q1..v_q{n}) and {E} couplings (v_c1..v_c{E})")
    if len(settings) == 0:
        raise ValueError("settings have no rows")
    twice = [c for c in columns if (settings.columns == c).sum() > 1]
    if twice:
        raise ValueError(f"settings have the column(s) {', '.join(twice[:8])} more than once")
    text = [c for c in columns if not pd.api.types.is_numeric_dtype(settings[c])]
    if text:
        raise ValueError(f"settings column(s) {', '.join(text[:8])} are not numeric")
    values = np.ascontiguousarray(settings[columns].to_numpy(dtype=float))
    bad = [c for c, ok in zip(columns, np.isfinite(values).all(axis=0)) if not ok]
    if bad:
        raise ValueError(f"settings column(s) {', '.join(bad[:8])} hold NaN or infinite values")
    source: int | np.random.SeedSequence | None = noise_seed
    if noise_seed is None and device_seed is not None:
        digest = hashlib.sha256(values.tobytes()).digest()
        source = np.random.SeedSequence([int(device_seed),
                                         int.from_bytes(digest[:16], "little")])
    draws = _readout_draws(np.random.default_rng(source), len(values), n)
    return _experiments(dev, Mismatch.default() if mismatch is None else mismatch,
                        values[:, :n], values[:, n:], draws, index=settings.index)


def write_simulation(sim: Simulation, out: str | Path) -> tuple[Path, Path]:
    """Write ``out`` (CSV, no index) and ``<out without .csv>.truth.json``, each atomically.

    Parameters
    ----------
    sim : Simulation
        What to write.
    out : str or Path
        The CSV file.

    Returns
    -------
    csv : Path
        The CSV written.
    truth : Path
        The truth sidecar written (``<out without .csv>.truth.json``).
    """
    out = Path(out)
    stem = out.with_suffix("") if out.suffix.lower() == ".csv" else out
    truth_path = stem.parent / f"{stem.name}.truth.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, sim.data.to_csv(index=False))
    atomic_write(truth_path, json.dumps(sim.truth, indent=1) + "\n")
    return out, truth_path
