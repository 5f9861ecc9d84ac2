"""The Google benchmark's device with the couplings its control model lacks, as a model file.

``hamiltonian_device.py``'s chain (five qubit frequencies f1..f5, the couplings g12..g45, the
targets the ascending eigenvalues of -H) plus the parasitic next-nearest couplings f1~f3,
f2~f4 and f3~f5 (:func:`workbench.param_boost.device_model`). They start at 0 and are
``OPTIONAL``: each is held at 0 (out of the model) until the selection gives it a covariate,
so CV decides whether the device has it, as ``hamiltonian_parasitic.toml``'s family does.
``experiments/parametric_parasitic.toml`` runs it through ``family = "parametric"``.
"""

from workbench.param_boost import device_model

DEVICE = device_model(["f1", "f2", "f3", "f4", "f5"], ["g12", "g23", "g34", "g45"],
                      parasitic="next_nearest")

PARAMETERS, predict, jacobian = DEVICE.file_functions()
OPTIONAL = list(DEVICE.optional)
