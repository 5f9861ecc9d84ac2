"""Nearest-neighbour chain Hamiltonians: batched construction, spectrum and its Jacobian.

A chain of N sites has parameters ``theta = (f_1..f_N, g_1..g_{N-1})``: onsite energies on
the diagonal of ``H`` and couplings ``g_i = H[i, i+1] = H[i+1, i]``. The spectrum of interest
is the ascending eigenvalues of ``sign * H`` (``sign = -1`` for the project's data).

Derivatives follow from Hellmann-Feynman. With ``M = sign * H`` and unit eigenvector ``u_k``
(the same for ``M`` and ``H``), ``d lambda_k / d theta = u_k^T (dM / d theta) u_k``, so::

    d lambda_k / d f_i = sign * u_ik^2
    d lambda_k / d g_i = sign * 2 u_ik u_{i+1,k}

At an exact degeneracy the eigenvalues are not differentiable; the values returned are the
derivatives of the sorted eigenvalue branch whose eigenvectors ``numpy.linalg.eigh`` chose.
They are always finite (eigh never returns NaN for finite input).
"""

from __future__ import annotations

import numbers

import numpy as np

__all__ = ["chain_hamiltonian", "chain_spectrum"]


def _check_chain(onsite, couplings) -> tuple[np.ndarray, np.ndarray]:
    f = np.asarray(onsite, dtype=float)
    g = np.asarray(couplings, dtype=float)
    if f.ndim != 2:
        raise ValueError(f"onsite must be 2-D (n_examples, n_sites), got shape {f.shape}")
    if g.ndim != 2:
        raise ValueError("couplings must be 2-D (n_examples, n_sites - 1), got shape "
                         f"{g.shape}")
    n, N = f.shape
    if N < 2:
        raise ValueError(f"a chain needs at least 2 sites; onsite has {N} column(s)")
    if g.shape != (n, N - 1):
        raise ValueError(f"couplings must have shape (n_examples, n_sites - 1) = ({n}, {N - 1})"
                         f" to match onsite {f.shape}, got {g.shape}")
    for name, a in (("onsite", f), ("couplings", g)):
        if not np.all(np.isfinite(a)):
            rows = np.flatnonzero(~np.isfinite(a).all(axis=1))[:10].tolist()
            raise ValueError(f"{name} contains NaN or infinite values (rows {rows})")
    return f, g


def _check_sign(sign) -> int:
    if isinstance(sign, bool) or not isinstance(sign, numbers.Real) or sign not in (-1, 1):
        raise ValueError(f"sign must be -1 or 1, got {sign!r}")
    return int(sign)


def chain_hamiltonian(onsite, couplings) -> np.ndarray:
    """Tridiagonal Hamiltonians, shape ``(n, N, N)``, from onsite ``(n, N)`` and couplings
    ``(n, N - 1)`` (arrays or DataFrames)."""
    f, g = _check_chain(onsite, couplings)
    n, N = f.shape
    h = np.zeros((n, N, N))
    d, u = np.arange(N), np.arange(N - 1)
    h[:, d, d] = f
    h[:, u, u + 1] = g
    h[:, u + 1, u] = g
    return h


def chain_spectrum(onsite, couplings, sign=-1) -> tuple[np.ndarray, np.ndarray]:
    """Ascending eigenvalues of ``sign * H`` and their Jacobian.

    Returns
    -------
    eigenvalues : ndarray of shape (n, N)
    jacobian : ndarray of shape (n, N, 2N - 1)
        ``jacobian[j, k, p] = d lambda_k / d theta_p`` for example ``j``, with
        ``theta = (onsite_1..onsite_N, coupling_1..coupling_{N-1})``.
    """
    sign = _check_sign(sign)
    h = chain_hamiltonian(onsite, couplings)
    N = h.shape[1]
    lam, vec = np.linalg.eigh(sign * h)  # vec[j, i, k] = u_ik of example j, ascending lam
    jac = np.empty((h.shape[0], N, 2 * N - 1))
    jac[:, :, :N] = sign * np.swapaxes(vec**2, 1, 2)
    jac[:, :, N:] = sign * 2.0 * np.swapaxes(vec[:, :-1, :] * vec[:, 1:, :], 1, 2)
    return lam, jac
