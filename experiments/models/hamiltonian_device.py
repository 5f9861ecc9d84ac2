"""The Google benchmark's device as a user's model file, made from the Hamiltonian family's physics.

The same chain as ``chain.py`` (five qubit frequencies f1..f5 on the diagonal of H, the four
nearest-neighbour couplings g12..g45 off it, the targets the ascending eigenvalues of -H), but
not rewritten: the functions are :class:`workbench.hamiltonian.HamiltonianModel`'s, the model
object the Hamiltonian family fits, handed over in the model-file contract by
``file_functions()``. So ``jacobian`` is the family's analytic Hellmann-Feynman Jacobian (no
finite differences), and ``family = "parametric"`` runs the device physics through the
generic parametric family (``experiments/parametric_device.toml``). Every parameter starts at
the control program's value for the experiment: the data column of its name.
"""

from workbench.hamiltonian import HamiltonianModel

DEVICE = HamiltonianModel.chain(["f1", "f2", "f3", "f4", "f5"], ["g12", "g23", "g34", "g45"])

PARAMETERS, predict, jacobian = DEVICE.file_functions()
