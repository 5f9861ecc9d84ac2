"""Loader for the IBM two-qubit gate benchmark: calibration snapshots of IBM Quantum devices.

The snapshots ship inside the wheel ``qiskit-ibm-runtime==0.51.0`` (Apache-2.0; its
``fake_provider`` backends, one ``props_<device>.json`` per device: the device's calibration
on one day, from 2020 to 2026). The loader fetches the wheel like the Google data
(:class:`~workbench.datasets.wheel.WheelData`: ``pip download --no-deps``, never installed,
the wheel and each of the 67 files checked against a pinned sha256, cached in
``$XDG_CACHE_HOME/workbench/ibm_gates`` or the directory ``$WORKBENCH_IBM_DATA_DIR`` names).

One row per two-qubit gate (``cx``, ``ecr`` or ``cz``, each direction of a pair its own row):

* **target** ``gate_error``: the gate's measured error (randomized benchmarking), in percent;
* **prior** ``coherence_limit``: the error the two qubits' T1 and T2 alone cause during the
  gate's length, in percent: per qubit the process fidelity of amplitude and phase damping
  for a time ``t``, ``F_q = (1 + exp(-t/T1) + 2 exp(-t/T2)) / 4`` (``T2`` capped at ``2 T1``,
  its physical bound), and the average gate infidelity ``4/5 (1 - F_a F_b)`` (dimension 4);
  the measured error is this plus what the control misses (leakage, crosstalk, miscalibration);
* **features**: the two qubits' T1 and T2 (us), readout errors and single-qubit gate errors
  (``sx``, ``u2`` on the oldest devices; percent), the gate's length (ns), the device's number
  of qubits and the gate type (one-hot).

Left out: the two snapshots that repeat another (``cambridge_alt``: cambridge's snapshot with
other basis gates; ``fractional``: lima's with fractional gates added), gates reported with
error 1 (IBM's mark of a gate out of service; every gate of ``kyoto``), gates on a qubit
without T1/T2 or whose single-qubit gate is out of service. Frequencies and anharmonicities
are missing for the newest devices, so they are not features.

Splits (``split``): ``"time"`` (default, the honest one): train on the snapshots taken before
2025-01-01, test on the newer ones (later devices, never seen whole, on a later date);
``"devices"``: 30% of the devices held out at random (``split_seed``). Never random rows: gates
of one device share its calibration.
"""

from __future__ import annotations

import json
import os
from datetime import date, datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .base import Dataset
from .wheel import WheelData

__all__ = ["FEATURES", "PRIOR", "TARGET", "TIME_SPLIT", "WHEEL", "coherence_limit",
           "gate_table", "load_ibm_gates"]

ENV_VAR = "WORKBENCH_IBM_DATA_DIR"
_MEMBER = "qiskit_ibm_runtime/fake_provider/backends/{0}/props_{0}.json"
#: device -> sha256 of its props file (every snapshot of the wheel but the two repeats)
_SHA256 = {
    "aachen": "ff432ea7e3e73c721fca1d4a63ddb8329d99ffbdb2e1657c20ee8c813919a1cc",
    "algiers": "187fa186510bb8eeca48c41ed415b091511bb4743ec4e0500b82cb8c00e1c57e",
    "almaden": "57e4307ab6bdb604f3cec2e2766aa049b8fb251152c5bc6c8d49ac86f86868ea",
    "armonk": "b82fae1e2050fbc1583dbf9884cce532f5bfbc50365d3d49ef029cf48a8eb211",
    "athens": "979c9d4406cc23fbebc03c9edb0dc6b2997bccaf8a923ecd21eeddcff05612c7",
    "auckland": "193c52a54c2b9a222f59cf85258aa9df2350c8f386d8ba2446becd2b6f426f0b",
    "belem": "9d57659789cff7aadab4dd870b07efaa9b01dd6602b6e44b663c8e2409e78169",
    "berlin": "f3873c80445e417d0164df35dbf012ae06b7a981e2d01b00c6913733820b98d6",
    "boeblingen": "eb63cc07e15fa24a36867eeef8dc9b429e97e04f69f15542a12137677840c155",
    "bogota": "dce442d71ad9671df6665b5fadfa7a0af534b620d63d4eb03c4e96dcef7faa3d",
    "boston": "7b01268dcd423c94bbed2b6d5550ee40a96122603974cde3c46d1aedb28c481d",
    "brisbane": "bc8b29433a8e1935a8f5537cafccc63194dc5ed5137edba684ff3fb77b269d1d",
    "brooklyn": "1993e2329fb08ec8921d714a5fb09fc0549f9daaf76550cb66f9d30f1dd82b48",
    "brussels": "2ffaffaeef258bcf920f86fd80179978313fe37367c137f1ca699389049648ac",
    "burlington": "006d0a561fe344c5c041d115396d5563792d8eb0213104701931d453675c95fa",
    "cairo": "870187e95b07b0c7dffce5d97726c79bfed7587c3c1315ee8c7491f55dc4f498",
    "cambridge": "87db4b8733c0c22ce5ace4418ed9ecb1d13c7323fba86ef9d793dedf1d702eef",
    "casablanca": "429dd2db681d7bb8cb4c45ecb653c9083cf43c9eb4f6d7c44d9cf6e9b2f0cc6d",
    "cusco": "a80a6a0ccc43a8c47e9655dba2c35e01b194eba76811ffa68c1e1309e33d81e0",
    "essex": "70133e7c5f79ca3395e711ff36af827db31d883edcdfb818ca923feda7406442",
    "fez": "7657d388bba0530c0c3cb7ebbb55d4f66c7cf5d21f81e55b4f97aaaf804b8693",
    "geneva": "e6d562954299add14a70187b477a6c52933857e4aa0f11dbf0b7e9505b94ba31",
    "guadalupe": "d937e2349009a67452c5c2e80a1e4a128f2c90cc39197bd38d464fca06454719",
    "hanoi": "17db2080056d895f74012ed0f45ae2cb8e93be564641640fadbd0ae4c28a5211",
    "jakarta": "29a90998e66c95580125b41456202ba0893a2ec37f467d15caa6aa8be3b34b43",
    "johannesburg": "e918440ce21d58aab9ac24a59fb31f61e83958363cdfe2f8bdc7636556e82ed3",
    "kawasaki": "38f17c3d3be4592e80d41855a71c84040954124c36406633f635b6482237e0c4",
    "kingston": "0ab157926fb5002a58ef1f5a240ffbe1adaf7facbebfb0f184f86d289785efa5",
    "kolkata": "93edd5e190cea17fb950f9c163f036f9e07737c32aa26faf6ab9fa61065e0b62",
    "kyiv": "1e84a0da150b1206fa87ca9066e778b30031ba460c5e2bfc6d794de0ce25db86",
    "kyoto": "95f71c6656f9fffb436b9ab68461d475d5cff9dbabcb30f23c04a5a69cfc32c7",
    "lagos": "55514b9331e1df2f06ac3f7494c112e3ea0c90a333f9363f47f62b4be13d8f66",
    "lima": "e1ee11907e8d1f907c0f8e2c8de001094cb258f7e3fa7d909127eff5f791bd2b",
    "london": "b9549fbf43cab2b0f7c4873b5132bcbe7263f963638e17d55ab93ff4bcd2ee2a",
    "manhattan": "609c5ba488a4c7f884aa5996390eef14e70ca774d3b23b1cd1f5b7124956d655",
    "manila": "5c1e0fe721a8e2fc00584007740db1b3d14cdf0c03cd033369187d4d4e2b1c24",
    "marrakesh": "d49d7ae07deb95947ea10e5b9b9c5cbab6df21f98610543817f35ade2b1aece6",
    "melbourne": "38565e8918b30ed0982efc7e7e30cc531f4f6c0fccac05ba55949e9d318e70ed",
    "miami": "670bc83f65a0302aa30d86dd1a919d459bb60d70d7c59a3812206d6ae77f0082",
    "montreal": "5ff486753fe466487b6c32877fa9713ce26a6de926388473541a6f6ef80b9119",
    "mumbai": "f5cdf6c7a9914d1e3923c76c4f8ac1ed7757c89e39c909f435364feaacb8cb4b",
    "nairobi": "92fc39e0c04e994d282e7494f7cc380d1a62907c00c3494a4fcae22c91f3fa75",
    "nighthawk": "c1f39f5683278a56a9fc786875c368443e02194606d39007ceb86020b0f43837",
    "osaka": "34fcb4ba74a378ca1cb4dba71f16af2500a54305860d742e02e58ecbfaed2904",
    "oslo": "4a42bae1774be1e28a872478868eddfa5b4b0728518bb2952304e0ceea156940",
    "ourense": "38f4a8f0a83b0d1d576e1521a86ac30ca321f4e2c6bb8cccfcf91f017e46bcf4",
    "paris": "d05754d40a544e99773f6ade28f3099fe2d71e820357a99aff2b9ebc163a20cf",
    "peekskill": "05c1850b79e831e8b08f94f57633a35f50f16f42853145c82eac839f268d58df",
    "perth": "b4a382621fc454dd57ee17e2e0c9336fbd757777c752775fb4db90d43fcf89c8",
    "pittsburgh": "72b986fb8df2342ab69a38adc7709e2e021b73510496b6321097230e3e801b9c",
    "poughkeepsie": "22852356654ae65b70661fcd89c1553e50596e433263da66ba09dec6d2f6af18",
    "prague": "075f3df8a60b3d5d9d3754440b7f5c9121144dc19f81dcfde63cdb9a8d93d4a5",
    "quebec": "06186af50e399fca8ec66dc1e21ccf505b425873f334535817ff4589b6fe1558",
    "quito": "2455172be07c605af209ea5559d139abf2e43d40a6da6d8c11bb2e600f294b85",
    "rochester": "2b761e856cb3f82a3ce2ad57ff59c5e17c03b3098ddd10bf90ba7ece3c4c5713",
    "rome": "f40deb752d81d3455e855f7a0336112e4fdc3a63d07eec70787de3d8ffbc99fd",
    "santiago": "eb56ca062ca62448c4da4b85e2f6f2fc905ef09a9813f9e1e3c6029b767216eb",
    "sherbrooke": "544c882d5df1fa23861808cce72af051ce4e962560f4f33f803b7335334c1a15",
    "singapore": "7f07badca428d6f05b676e65718ebf55e3014f55f82ea0542ff66d3f16714c23",
    "strasbourg": "e71754972072e75d4e7504546ea88a247298c8043e6e0c0828272ffc938e9f71",
    "sydney": "91b0573bb10da6e0737c6f175dd7d0616d796b895a09aa40d0b768b667fc619a",
    "torino": "116c5692ad5669219571ce4c13132fdd68394aa543537b5ccf14a6bd2df10b11",
    "toronto": "c52350639adee1b460fb0e3a5aa002be961efcdb2d55fde4cebb0b64134d0013",
    "valencia": "f9f329eab777e027e63b9736121576f6e964d7564ea117c27e8fb8a95a90259a",
    "vigo": "b276a65066485007302f6e06555942eba9bfe82bab9cda37e92748abc3bc609c",
    "washington": "7c30d6c731810719438df47fc7695d5e1275f156221fe28d4bbeb7c74c9b5190",
    "yorktown": "378596833d40268b937136cc38dbd3ab5a5f697d3b9fee7634591cb41e6e7b87",
}
WHEEL = WheelData(
    name="ibm_gates", spec="qiskit-ibm-runtime==0.51.0",
    sha256="eb3fd3dbf09e7a066106fc557bb4beb8a3cbf3cbc40623c8e9647db00ed7c28c",
    files={f"props_{d}.json": (_MEMBER.format(d), sha) for d, sha in _SHA256.items()},
    env_var=ENV_VAR)

TARGET = "gate_error"
PRIOR = "coherence_limit"
FEATURES = ["t1_a_us", "t1_b_us", "t2_a_us", "t2_b_us", "readout_error_a", "readout_error_b",
            "sx_error_a", "sx_error_b", "gate_length_ns", "n_qubits", "gate_cx", "gate_ecr",
            "gate_cz"]
GATES = ("cx", "ecr", "cz")
#: the single-qubit gate whose error describes a qubit (``u2`` before the ``sx`` basis)
ONE_QUBIT = ("sx", "u2")
#: snapshots on or after this date are the time split's test rows
TIME_SPLIT = date(2025, 1, 1)
DEVICES_TEST_FRACTION = 0.3
UNITS = {"T1": ("us", "µs"), "T2": ("us", "µs"), "gate_length": ("ns",), "gate_error": ("",),
         "readout_error": ("",)}


def coherence_limit(length_ns: ArrayLike, t1_a: ArrayLike, t2_a: ArrayLike, t1_b: ArrayLike,
                    t2_b: ArrayLike) -> np.ndarray:
    """The average gate infidelity (a fraction) that T1 and T2 (us) of two qubits alone cause
    in a gate of ``length_ns``: ``4/5 (1 - F_a F_b)``, ``F = (1 + e^(-t/T1) + 2 e^(-t/T2))/4``,
    ``T2`` capped at ``2 T1``.

    Parameters
    ----------
    length_ns : array-like
        The gate's length (ns).
    t1_a, t2_a, t1_b, t2_b : array-like
        The two qubits' T1 and T2 (us).

    Returns
    -------
    ndarray
        The infidelity.
    """
    t = np.asarray(length_ns, dtype=float) * 1e-3

    def fidelity(t1: Any, t2: Any) -> np.ndarray:
        t1 = np.asarray(t1, dtype=float)
        t2 = np.minimum(np.asarray(t2, dtype=float), 2 * t1)
        return (1 + np.exp(-t / t1) + 2 * np.exp(-t / t2)) / 4

    return 0.8 * (1 - fidelity(t1_a, t2_a) * fidelity(t1_b, t2_b))


def _values(entries: list[dict], where: str) -> dict[str, Any]:
    """``name -> value`` of a props list, units checked for the quantities used."""
    out: dict[str, Any] = {}
    for e in entries:
        name = str(e.get("name"))
        if name in UNITS and e.get("unit") not in UNITS[name]:
            raise WHEEL.fail(f"{where}: {name} in unit {e.get('unit')!r}, expected "
                             f"{' or '.join(repr(u) for u in UNITS[name])}")
        out[name] = e.get("value")
    return out


def _name(gate: dict) -> str:
    """A gate's name as the file gives it, or as IBM writes it (``cx0_1``)."""
    return gate.get("name") or f"{gate['gate']}{'_'.join(str(q) for q in gate['qubits'])}"


def _device_rows(device: str, props: dict) -> list[dict]:
    """The kept two-qubit gates of one snapshot, as rows (see the module docstring)."""
    where = f"props_{device}.json"
    snapshot = datetime.fromisoformat(props["last_update_date"])
    qubits = [_values(q, f"{where} qubit {i}") for i, q in enumerate(props["qubits"])]
    one: dict[int, dict[str, Any]] = {}
    for g in props["gates"]:
        if g["gate"] in ONE_QUBIT and len(g["qubits"]) == 1:
            one[g["qubits"][0]] = _values(g["parameters"], f"{where} {_name(g)}")
    rows = []
    for g in props["gates"]:
        if g["gate"] not in GATES or len(g["qubits"]) != 2:
            continue
        p = _values(g["parameters"], f"{where} {_name(g)}")
        a, b = g["qubits"]
        qa, qb = qubits[a], qubits[b]
        sx_a: Any = one.get(a, {}).get("gate_error")
        sx_b: Any = one.get(b, {}).get("gate_error")
        needed = [p.get("gate_error"), p.get("gate_length"), qa.get("T1"), qa.get("T2"),
                  qb.get("T1"), qb.get("T2"), sx_a, sx_b, qa.get("readout_error"),
                  qb.get("readout_error")]
        if any(v is None for v in needed) or max(p["gate_error"], sx_a, sx_b) >= 1:
            continue
        rows.append({
            "device": device, "snapshot": snapshot.date().isoformat(), "gate": _name(g),
            TARGET: 100 * p["gate_error"],
            PRIOR: 100 * float(coherence_limit(p["gate_length"], qa["T1"], qa["T2"], qb["T1"],
                                               qb["T2"])),
            "t1_a_us": qa["T1"], "t1_b_us": qb["T1"], "t2_a_us": qa["T2"], "t2_b_us": qb["T2"],
            "readout_error_a": 100 * qa["readout_error"],
            "readout_error_b": 100 * qb["readout_error"],
            "sx_error_a": 100 * sx_a, "sx_error_b": 100 * sx_b,
            "gate_length_ns": p["gate_length"], "n_qubits": len(qubits),
            **{f"gate_{k}": float(g["gate"] == k) for k in GATES},
        })
    return rows


def gate_table(data_dir: str | os.PathLike[str] | None = None, *,
               download: bool = True) -> pd.DataFrame:
    """Every kept two-qubit gate of every snapshot: ``device``, ``snapshot`` (the date),
    ``gate`` (its name, e.g. ``ecr62_72``), the target, the prior and the features; one row
    per gate, devices in alphabetical order, gates in the file's order.

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the files are (``None``: the user cache).
    download : bool, default=True
        Whether to fetch (and verify) the files when they are missing.

    Returns
    -------
    pandas.DataFrame
        The gates.
    """
    directory = WHEEL.directory(data_dir, download=download)
    rows: list[dict] = []
    for name in sorted(WHEEL.files):
        path = Path(directory) / name
        try:
            props = json.loads(path.read_text(encoding="utf-8"))
            rows += _device_rows(name[len("props_"):-len(".json")], props)
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            raise WHEEL.fail(f"cannot read {path}: {exc!r}") from exc
    table = pd.DataFrame(rows)
    numeric = [TARGET, PRIOR, *FEATURES]
    table[numeric] = table[numeric].astype(np.float64)
    if not np.isfinite(table[numeric].to_numpy()).all():
        raise WHEEL.fail("a kept gate has a non-finite value")
    return table


def load_ibm_gates(data_dir: str | os.PathLike[str] | None = None, *,
                   split: Literal["time", "devices"] = "time", split_seed: int = 0,
                   download: bool = True) -> Dataset:
    """The IBM two-qubit gate benchmark (see the module docstring) with its ``split``.

    ``groups`` holds each row's device.

    Parameters
    ----------
    data_dir : str or path-like, default=None
        Where the snapshots are (``None``: the loader's cache).
    split : {"time", "devices"}, default="time"
        ``"time"``: the snapshots from 2025 on are the test rows; ``"devices"``: the gates of
        30% of the devices, held out at random.
    split_seed : int, default=0
        Which devices the ``"devices"`` split holds out.
    download : bool, default=True
        Whether to fetch (and verify) the wheel when it is missing.

    Returns
    -------
    Dataset
        The data and their split.

    Raises
    ------
    DataUnavailableError
        When the files cannot be found, fetched or verified.
    ValueError
        For an unknown split.
    """
    table = gate_table(data_dir, download=download)
    devices = table["device"]
    if split == "time":
        test = pd.to_datetime(table["snapshot"]) >= pd.Timestamp(TIME_SPLIT)
    elif split == "devices":
        names = np.array(sorted(devices.unique()))
        rng = np.random.default_rng(split_seed)
        held = rng.choice(names, size=round(DEVICES_TEST_FRACTION * len(names)), replace=False)
        test = devices.isin(held)
    else:
        raise ValueError(f"unknown split {split!r}; the splits are 'time', 'devices'")
    index = table.index.to_numpy()
    return Dataset(name="ibm_gates", features=table[FEATURES].copy(),
                   prior=table[[PRIOR]].copy(), targets=table[[TARGET]].copy(),
                   train_index=index[~test.to_numpy()], test_index=index[test.to_numpy()],
                   groups=devices.copy(), unit="%", prior_label="coherence limit")
