"""Make ``transmon_flux.csv``: a flux-tunable transmon's f01 and f12 measured over a month.

Simulated with ``experiments/models/transmon_scqubits.py`` (scqubits) at parameters that are
not the design values and drift: the junctions age (``EJmax`` falls 60 MHz a day), trapped
flux builds up (the flux offset grows 0.003 flux quanta a day), the charging energy and the
SQUID's asymmetry are off their design values but constant; the fridge's temperature
(``temp_mK``) is recorded and plays no part. Each row: a day, an applied flux, the two
measured frequencies with 2 MHz of noise. Run from the repository's root::

    python experiments/datasets/transmon_flux.py

Needs the optional extra ``toolbox`` (scqubits).
"""

from pathlib import Path

import numpy as np
import pandas as pd

from workbench.parametric import load_model

HERE = Path(__file__).resolve().parent
ROWS, NOISE_GHZ, SEED = 90, 0.002, 0


def simulate(rows: int = ROWS, seed: int = SEED) -> pd.DataFrame:
    """The data set: ``day``, ``flux``, ``temp_mK``, ``f01_GHz``, ``f12_GHz``."""
    rng = np.random.default_rng(seed)
    data = pd.DataFrame({"day": rng.integers(0, 31, rows).astype(float),
                         "flux": rng.uniform(-0.45, 0.45, rows).round(4),
                         "temp_mK": rng.uniform(10.0, 30.0, rows).round(1)})
    model = load_model(HERE.parent / "models" / "transmon_scqubits.py")
    day = data["day"].to_numpy()
    truth = np.column_stack([21.0 - 0.06 * day, np.full(rows, 0.242), np.full(rows, 0.13),
                             0.02 + 0.003 * day])       # EJmax, EC, d, flux_offset
    f = model.predict(truth, data, 2) + rng.normal(0.0, NOISE_GHZ, (rows, 2))
    return data.assign(f01_GHz=f[:, 0].round(5), f12_GHz=f[:, 1].round(5))


if __name__ == "__main__":
    simulate().to_csv(HERE / "transmon_flux.csv", index=False)
    print(f"wrote {HERE / 'transmon_flux.csv'}")
