"""Pitzer's critical compressibility as a user's model file: critical volumes.

``Vc = Zc R Tc / Pc`` with ``Zc = a - b omega``: the corresponding-states correlation of the
critical compressibility factor with the acentric factor, ``a = 0.291`` and ``b = 0.080``
(K. S. Pitzer et al., J. Am. Chem. Soc. 77 (1955) 3433; e.g. B. E. Poling, J. M. Prausnitz and
J. P. O'Connell, *The Properties of Gases and Liquids*, 5th ed., McGraw-Hill 2001, ch. 2).
Two parameters; Tc in kelvin, Pc in bar, ``predict`` returns cm^3/mol. Polar and associating
fluids stray from the line. No ``jacobian``: finite differences.
"""

PARAMETERS = {"a": 0.291, "b": 0.080}
R_CM3_BAR = 83.14462618  # cm^3 bar / (mol K)


def predict(params, data):
    tc = data["Tc"].to_numpy(float)
    pc = data["Pc_bar"].to_numpy(float)
    omega = data["omega"].to_numpy(float)
    return (params["a"] - params["b"] * omega) * R_CM3_BAR * tc / pc
