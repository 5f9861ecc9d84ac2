"""Kistiakowsky's entropy of vaporization (Trouton's rule refined) as a user's model file.

``Hvap(Tb) = Tb (a + b ln Tb)``: the entropy of vaporization at the normal boiling point is
about ``36.1 + R ln Tb`` J/(mol K) for non-polar liquids (G. B. Kistiakowsky, Z. Phys. Chem.
107 (1923) 65; e.g. B. E. Poling, J. M. Prausnitz and J. P. O'Connell, *The Properties of
Gases and Liquids*, 5th ed., McGraw-Hill 2001, ch. 7). Two parameters, ``a`` in J/(mol K)
and ``b`` (R at the start); Tb in kelvin, ``predict`` returns kJ/mol. Hydrogen-bonded and
metallic liquids lose more entropy than the rule holds, a term the formula lacks. No
``jacobian``: finite differences.
"""

import numpy as np

PARAMETERS = {"a": 36.1, "b": 8.314462618}


def predict(params, data):
    tb = data["Tb"].to_numpy(float)
    return tb * (params["a"] + params["b"] * np.log(tb)) / 1000.0
