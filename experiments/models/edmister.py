"""Edmister's acentric factor as a user's model file.

``omega = a theta / (1 - theta) log10(Pc / 1 atm) - b`` with ``theta = Tb / Tc``: the
Clausius-Clapeyron line through the normal boiling point and the critical point, read at
``Tr = 0.7`` (W. C. Edmister, Petrol. Refiner 37 (1958) 173; e.g. B. E. Poling, J. M. Prausnitz
and J. P. O'Connell, *The Properties of Gases and Liquids*, 5th ed., McGraw-Hill 2001, ch. 2).
Two parameters, ``a = 3/7`` and ``b = 1``; Tb and Tc in kelvin, Pc in bar. The vapour-pressure
curve bends where the line does not, more as theta grows. No ``jacobian``: finite differences.
"""

import numpy as np

PARAMETERS = {"a": 3.0 / 7.0, "b": 1.0}
ATM_BAR = 1.01325


def predict(params, data):
    theta = data["Tb"].to_numpy(float) / data["Tc"].to_numpy(float)
    log_pc = np.log10(data["Pc_bar"].to_numpy(float) / ATM_BAR)
    return params["a"] * theta / (1.0 - theta) * log_pc - params["b"]
