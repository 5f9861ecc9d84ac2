"""Guldberg's rule for the critical temperature as a user's model file.

``Tc = ratio * Tb``: a liquid's critical temperature is about 3/2 of its normal boiling
point (C. M. Guldberg, 1890; e.g. B. E. Poling, J. M. Prausnitz and J. P. O'Connell,
*The Properties of Gases and Liquids*, 5th ed., McGraw-Hill 2001, ch. 2). One parameter, the
ratio; kelvin in and out. Its error is not a drift of the ratio alone (molecular size and
polarity change it, as group-contribution methods add), which is what the second outside
field of ``benchmarks/parametric_outside.py`` tests. No ``jacobian``: finite differences.
"""

PARAMETERS = {"ratio": 1.5}


def predict(params, data):
    return params["ratio"] * data["Tb"].to_numpy(float)
