"""
Boosting from a physics prior
=============================

A toy "scientific model" predicts ``sin(x)``; the truth adds a slow drift the model misses.
:class:`~workbench.BaseBoostRegressor` starts from the prior's prediction and fits one stage
of a ridge basis to what is left; ordinary gradient boosting (``prior=None``) starts from the
mean and has to learn the whole curve from 60 noisy points.
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from sklearn.linear_model import Ridge
from sklearn.metrics import mean_absolute_error

from workbench import BaseBoostCV, BaseBoostRegressor

rng = np.random.default_rng(0)
x = np.sort(rng.uniform(0, 10, 80))
truth = np.sin(x) + 0.15 * x
X = pd.DataFrame({"x": x, "prior": np.sin(x)})
y = truth + rng.normal(0, 0.1, x.size)
train = rng.permutation(x.size) < 60

# %%
# One stage of a ridge basis on top of the prior (the basis sees ``x`` only), and the same
# basis started from the mean. :class:`~workbench.BaseBoostCV` keeps the prior alone unless
# cross-validation on the training rows says the stage helps.
boosted = BaseBoostCV(BaseBoostRegressor(prior="prior", basis=Ridge(alpha=1.0),
                                         basis_features=["x"], random_state=0), cv=5)
boosted.fit(X[train], y[train])
from_mean = BaseBoostRegressor(prior=None, basis=Ridge(alpha=1.0), n_stages=3,
                               basis_features=["x"], random_state=0).fit(X[train], y[train])

for label, pred in [("prior alone", X["prior"]), ("base boosting", boosted.predict(X)),
                    ("boosting from the mean", from_mean.predict(X))]:
    print(f"{label:24s} test MAE {mean_absolute_error(y[~train], pred[~train]):.3f}")
print("BaseBoostCV kept:", boosted.selected_)

# %%
# The prior gets the shape, the stage the drift; from the mean, three ridge stages can only
# draw a line.
fig, ax = plt.subplots(figsize=(7, 4))
ax.scatter(x[train], y[train], s=12, color="0.6", label="training rows")
ax.plot(x, X["prior"], "--", label="prior (physics)")
ax.plot(x, boosted.predict(X), label="base boosting")
ax.plot(x, from_mean.predict(X), ":", label="boosting from the mean")
ax.set_xlabel("x")
ax.set_ylabel("y")
ax.legend()
fig.tight_layout()
