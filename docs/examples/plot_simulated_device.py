"""
A simulated device with the eigenvalue config
=============================================

:func:`workbench.simulate.simulate` draws random bias settings of a 5-site chain of tunable
transmons; the "true device" departs from the control model in named ways (drift,
crosstalk, ...). The control model's eigenvalues are the priors, the measured eigenvalues
the targets. The estimators below are those ``experiments/simulated_device.toml`` configures
(kernel ridge basis on the priors and voltages, two Huber stages), fitted on 70% of the rows.
"""

import matplotlib.pyplot as plt
import numpy as np
from sklearn.preprocessing import StandardScaler

from workbench import BaseBoostCV, BaseBoostRegressor, MultiTargetBaseBoost, make_basis
from workbench.simulate import simulate

sim = simulate(n_sites=5, n_experiments=300, device_seed=0)
data = sim.data
priors = [f"model_E{i}" for i in range(1, 6)]
targets = [f"measured_E{i}" for i in range(1, 6)]
voltages = [c for c in data.columns if c.startswith(("v_q", "v_c"))]
print("injected mismatches:", ", ".join(k for k, v in sim.truth["mismatch"].items() if v))

rng = np.random.default_rng(0)
train = rng.permutation(len(data)) < int(0.7 * len(data))
X = data[voltages + priors]
Y = data[targets]

# %%
# One :class:`~workbench.BaseBoostCV` per target, target *j* boosting from prior column *j*.
booster = BaseBoostRegressor(basis=make_basis("kernel_ridge", alpha=0.1, gamma=0.05),
                             n_stages=2, loss="huber", line_search_loss="absolute_error",
                             input_transform=StandardScaler(), random_state=0)
model = MultiTargetBaseBoost(BaseBoostCV(booster, cv=5), priors=priors, random_state=0)
model.fit(X[train], Y[train])
pred = model.predict(X[~train])

truth = Y[~train].to_numpy()
prior_mae = np.abs(X.loc[~train, priors].to_numpy() - truth).mean(axis=0)
model_mae = np.abs(pred.to_numpy() - truth).mean(axis=0)
for t, p, m in zip(targets, prior_mae, model_mae):
    print(f"{t}: control model {p:.3f} MHz, base boosting {m:.3f} MHz")

# %%
# Test MAE per eigenvalue: the control model against base boosting.
fig, ax = plt.subplots(figsize=(7, 3.5))
pos = np.arange(len(targets))
ax.bar(pos - 0.2, prior_mae, 0.4, label="control model (prior)")
ax.bar(pos + 0.2, model_mae, 0.4, label="base boosting")
ax.set_xticks(pos, [f"E{i}" for i in range(1, 6)])
ax.set_ylabel("test MAE, MHz")
ax.legend()
fig.tight_layout()
