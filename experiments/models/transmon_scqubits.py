"""A flux-tunable transmon's spectrum from scqubits, as a user's model file.

A quantum-device physicist's model: the qubit's two lowest transition frequencies, f01 and
f12 (GHz), from scqubits' ``TunableTransmon`` (the charge-basis Hamiltonian
``4 EC (n - ng)^2 - EJ(flux) cos(phi)`` with a SQUID's ``EJ(flux) = EJmax sqrt(cos^2(pi
flux) + d^2 sin^2(pi flux))``, diagonalised numerically) at each row's applied flux
(column ``flux``, in flux quanta). Four parameters start at their design values: the
junctions' ``EJmax`` and the charging energy ``EC`` (GHz), the SQUID's asymmetry ``d`` and a
flux offset (trapped flux, in flux quanta). ``jacobian`` gives the exact derivatives from
the same diagonalisation (Hellmann-Feynman: the eigenstates' matrix elements of each
parameter's derivative of the Hamiltonian), so the fit needs no finite differences.

Needs the optional extra: ``pip install "workbench[toolbox]"`` (scqubits). Data:
``experiments/datasets/transmon_flux.csv`` (made by ``experiments/datasets/transmon_flux.py``);
config: ``experiments/parametric_transmon.toml``.
"""

import numpy as np
import scqubits

PARAMETERS = {"EJmax": 20.0, "EC": 0.25, "d": 0.10, "flux_offset": 0.0}
NCUT = 10  # charge states -NCUT..NCUT: converged for EJ/EC > 20 to far below 1 kHz

_qubit = scqubits.TunableTransmon(EJmax=20.0, EC=0.25, d=0.1, flux=0.0, ng=0.0, ncut=NCUT,
                                  truncated_dim=3)
_n2 = np.diag(np.arange(-NCUT, NCUT + 1) ** 2.0)            # (n - ng)^2 at ng = 0
_cos = _qubit.cos_phi_operator()                                # charge basis


def _levels(params, data):
    """Each row's three lowest energies and their eigenvectors (charge basis)."""
    flux = data["flux"].to_numpy(float) + params["flux_offset"]
    energies, vectors = [], []
    for i, phi in enumerate(flux):
        _qubit.EJmax, _qubit.EC, _qubit.d = params["EJmax"][i], params["EC"][i], params["d"][i]
        _qubit.flux = phi
        e, v = _qubit.eigensys(evals_count=3)
        energies.append(e)
        vectors.append(v)
    return flux, np.array(energies), np.array(vectors)


def predict(params, data):
    _, e, _ = _levels(params, data)
    return np.column_stack([e[:, 1] - e[:, 0], e[:, 2] - e[:, 1]])   # f01, f12


def jacobian(params, data):
    flux, _, v = _levels(params, data)
    ej_max, d = params["EJmax"], params["d"]
    c, s = np.cos(np.pi * flux), np.sin(np.pi * flux)
    root = np.sqrt(c**2 + d**2 * s**2)
    # dEJ/dtheta for EJmax, d, flux: EJ = EJmax * root
    d_ej = [root, ej_max * d * s**2 / root, ej_max * np.pi * (d**2 - 1) * c * s / root]
    cos_k = np.einsum("rik,ij,rjk->rk", v, _cos, v)               # <k|cos phi|k>
    n2_k = np.einsum("rik,ij,rjk->rk", v, _n2, v)                 # <k|(n - ng)^2|k>
    dE = np.stack([-d_ej[0][:, None] * cos_k, 4 * n2_k,           # d E_k / d EJmax, d EC
                   -d_ej[1][:, None] * cos_k, -d_ej[2][:, None] * cos_k], axis=2)
    return np.stack([dE[:, 1] - dE[:, 0], dE[:, 2] - dE[:, 1]], axis=1)  # (rows, 2, 4)
