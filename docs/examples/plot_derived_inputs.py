"""
Physics-derived inputs
======================

:class:`~workbench.PriorDerivedInputs` appends the priors' pairwise differences and ratios,
their logs and prior x feature products to a basis' inputs. Here the model's error depends on
the *gap* between two predicted levels, a single column once derived and a diagonal that a
tree must staircase when it is not.
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from lightgbm import LGBMRegressor
from sklearn.metrics import mean_absolute_error
from sklearn.preprocessing import StandardScaler

from workbench import BaseBoostRegressor, PriorDerivedInputs

rng = np.random.default_rng(1)
n = 600
p1 = rng.uniform(4.0, 6.0, n)
p2 = rng.uniform(4.0, 6.0, n)
gap = p2 - p1
# the truth: the prior plus a shift that grows as the levels approach (an avoided crossing)
y = p1 + 0.3 / (0.2 + np.abs(gap)) + rng.normal(0, 0.02, n)
X = pd.DataFrame({"p1": p1, "p2": p2})
train = np.arange(n) < 400

# %%
# The same LightGBM basis, with and without the derived columns (``n_priors=2``: both
# columns are priors; standardised afterwards).
basis = LGBMRegressor(n_estimators=100, learning_rate=0.1, num_leaves=8, verbose=-1,
                      random_state=0)
plain = BaseBoostRegressor(prior="p1", basis=basis, random_state=0).fit(X[train], y[train])
derived = BaseBoostRegressor(
    prior="p1", basis=basis, random_state=0,
    input_transform=PriorDerivedInputs(n_priors=2, kinds=["differences"],
                                       then=StandardScaler()),
).fit(X[train], y[train])
for label, est in [("plain inputs", plain), ("derived inputs", derived)]:
    print(f"{label:15s} test MAE {mean_absolute_error(y[~train], est.predict(X[~train])):.4f}")

# %%
# The learned correction against the gap: the derived column lets the trees follow the
# peak at zero gap.
order = np.argsort(gap[~train])
fig, ax = plt.subplots(figsize=(7, 4))
ax.scatter(gap[~train], (y - p1)[~train], s=8, color="0.6", label="truth - prior (test)")
for label, est in [("plain inputs", plain), ("derived inputs", derived)]:
    ax.plot(gap[~train][order], (est.predict(X[~train]) - p1[~train])[order], label=label)
ax.set_xlabel("p2 - p1")
ax.set_ylabel("correction")
ax.legend()
fig.tight_layout()
