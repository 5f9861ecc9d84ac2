"""The liquid-drop model of the nucleus (the semi-empirical mass formula) as a user's model file.

Binding energy ``B = a_v A - a_s A^(2/3) - a_c Z (Z - 1) / A^(1/3) - a_a (N - Z)^2 / A
+ delta``, the pairing ``delta = +a_p / sqrt(A)`` for even-even nuclei, ``-a_p / sqrt(A)``
for odd-odd ones, 0 otherwise; textbook coefficients in MeV (e.g. R. A. Rohlf, *Modern
Physics from alpha to Z0*, Wiley 1994). ``predict`` returns the atomic mass excess in MeV
(Z hydrogen atoms and N neutrons, less the binding), as ``benchmarks/outside_data.py``'s
prior. No ``jacobian``: the workbench takes central finite differences.
"""

import numpy as np

PARAMETERS = {"a_v": 15.75, "a_s": 17.8, "a_c": 0.711, "a_a": 23.7, "a_p": 11.18}
U_MEV = 931.49410242                      # MeV per atomic mass unit
EXCESS_H, EXCESS_N = (1.00782503190 - 1) * U_MEV, (1.00866491582 - 1) * U_MEV  # AME2020


def predict(params, data):
    z, n = data["Z"].to_numpy(float), data["N"].to_numpy(float)
    a = z + n
    parity = 1.0 - (z % 2) - (n % 2)      # +1 even-even, -1 odd-odd, 0 odd A
    binding = (params["a_v"] * a - params["a_s"] * a ** (2 / 3)
               - params["a_c"] * z * (z - 1) / a ** (1 / 3)
               - params["a_a"] * (n - z) ** 2 / a + params["a_p"] * parity / np.sqrt(a))
    return z * EXCESS_H + n * EXCESS_N - binding
