"""The Google benchmark's control model as a user's model file (workbench's parametric family).

Five transmon qubits in a chain: their frequencies f1..f5 on the diagonal of a Hamiltonian,
the four nearest-neighbour couplings g12..g45 off it. The measured single-excitation
energies are the eigenvalues of -H, in ascending order (the targets eeig1..eeig5). Every
parameter starts at the control program's value for the experiment: a column of the data.
No ``jacobian``: the workbench takes central finite differences.
"""

import numpy as np

SITES = ["f1", "f2", "f3", "f4", "f5"]
COUPLINGS = ["g12", "g23", "g34", "g45"]

#: each parameter starts at the control program's per-experiment value (a data column)
PARAMETERS = {name: name for name in SITES + COUPLINGS}


def predict(params, data):
    n, N = len(data), len(SITES)
    H = np.zeros((n, N, N))
    for i, f in enumerate(SITES):
        H[:, i, i] = params[f]
    for i, g in enumerate(COUPLINGS):
        H[:, i, i + 1] = H[:, i + 1, i] = params[g]
    return np.linalg.eigvalsh(-H)  # (rows, 5), ascending
