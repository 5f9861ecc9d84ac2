"""A hydrogen-like ionization energy with Slater's screening constants, as a user's model file.

``IE = Ry ((Z - S) / n*)^2``: the outermost electron sees the nuclear charge ``Z`` less the
screening ``S = s_same * same + s_inner * inner + s_deep * deep`` of the other electrons
(Slater's rules: 0.35 for each other electron in its group, 0.30 in 1s; 0.85 for each in shell
n-1 when it is an s or p electron; 1.00 for each deeper one, and for a d or f electron for
every electron in a group to its left), and ``n*`` is Slater's effective quantum number (1, 2,
3, 3.7, 4.0, 4.2 for n = 1 to 6). J. C. Slater, Phys. Rev. 36 (1930) 57; e.g. P. Atkins and
J. de Paula, *Physical Chemistry*, 8th ed., OUP 2006, ch. 10. Four parameters (the Rydberg
energy in eV and the three screening constants), the 1s constant kept at 0.30. The
features are ``benchmarks/outside_fields.py``'s counts; ``predict`` returns ``ln(IE / eV)``.
No ``jacobian``: finite differences.
"""

import numpy as np

PARAMETERS = {"rydberg": 13.605693, "s_same": 0.35, "s_inner": 0.85, "s_deep": 1.0}
N_STAR = np.array([np.nan, 1.0, 2.0, 3.0, 3.7, 4.0, 4.2])   # Slater's n* by n


def predict(params, data):
    z, n = data["Z"].to_numpy(float), data["n"].to_numpy(int)
    same = np.where(n == 1, 0.30, params["s_same"]) * data["same"].to_numpy(float)
    screening = (same + params["s_inner"] * data["inner"].to_numpy(float)
                 + params["s_deep"] * data["deep"].to_numpy(float))
    z_eff = np.maximum(np.abs(z - screening), 1e-6)
    return np.log(params["rydberg"]) + 2.0 * np.log(z_eff) - 2.0 * np.log(N_STAR[n])
