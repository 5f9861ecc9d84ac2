"""
Your own model, corrected in its parameter space
================================================

Hand over the physics model itself, not only its prediction: a dict of parameters with their
start values and a ``predict(params, data)`` function (in a config: a Python file, see
:doc:`/user_guide/parametric`). Here a capacitor discharges through a resistor whose value
drifts with the temperature: the textbook law ``V(t) = V0 exp(-t / tau) + V_off`` is right,
its time constant ``tau`` is not a constant. :class:`~workbench.ParametricBoostRegressor`
calibrates the three parameters, then lets each drift linearly in covariates chosen by CV,
and says which of prior, calibrated model and drift won.
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from workbench import ParametricBoostRegressor, ParametricModel

PARAMETERS = {"V0": 5.0, "tau": 1.0, "V_off": 0.0}  # start values (a datasheet's)


def predict(params, data):
    t = data["t"].to_numpy()
    return params["V0"] * np.exp(-t / params["tau"]) + params["V_off"]


model = ParametricModel.from_functions(PARAMETERS, predict)  # no jacobian: finite differences

rng = np.random.default_rng(0)
n = 300
data = pd.DataFrame({"t": rng.uniform(0, 4, n), "temp": rng.uniform(10, 40, n),
                     "humidity": rng.uniform(20, 80, n)})
tau = 1.2 + 0.02 * (data["temp"] - 25)  # the resistor warms up
v = 4.8 * np.exp(-data["t"] / tau) + 0.05 + rng.normal(0, 0.01, n)
train = np.arange(n) < 200

# %%
# Prior, calibrated model and drift, scored by 5-fold CV on the training rows.
est = ParametricBoostRegressor(model=model, features=["temp", "humidity"], loss="squared_error",
                               max_steps=4, random_state=0).fit(data[train], v[train])
print(est.choices_.to_string(index=False))
print(est.estimator_.coefficient_table().to_string(index=False))
test_mae = np.abs(est.predict(data[~train]) - v[~train]).mean()
print(f"test MAE of the chosen model: {test_mae:.4f} V")

# %%
# The corrected time constant against the temperature: the drift the data asked for.
corrected = est.corrected_parameters(data[~train])
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.scatter(data["temp"][~train], corrected["tau"], s=10, label="corrected tau (test rows)")
ax.plot([10, 40], [1.2 - 0.3, 1.2 + 0.3], color="0.3", label="true tau")
ax.set_xlabel("temperature (deg C)")
ax.set_ylabel("tau (s)")
ax.legend()
fig.tight_layout()
