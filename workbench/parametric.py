"""A user's physics model as a Python file: loading, evaluating and checking it.

The contract (a file, ``model.py``, that defines):

* ``PARAMETERS``: a dict from each parameter's name to its starting value (a float), or to
  the name of a data column holding a per-row value (e.g. a control program's parameters
  of each experiment);
* ``predict(params, data)``: ``params`` a dict from name to a 1-d array (one value per
  row), ``data`` a pandas DataFrame of the data set's columns; returns an array of shape
  ``(rows,)`` for one target or ``(rows, targets)`` in the targets' order;
* optionally ``jacobian(params, data)``: ``d predict / d params`` of shape
  ``(rows, targets, parameters)`` in ``PARAMETERS``' order. Without it, the derivatives are
  central finite differences with a step scaled to each parameter;
* optionally ``OPTIONAL``: a list of parameters (each with a number as its start) that are
  terms the model may lack, e.g. a coupling the control program leaves out: each is held at
  its start value and gets no calibration offset until a fit's covariates name it (the
  selection offers it like any parameter, CV decides whether it enters).

:func:`load_model` reads such a file (or :meth:`ParametricModel.from_functions` builds the
same from Python objects); :func:`check_model` evaluates it on data and raises a
:class:`ModelError`, one line naming the problem, for every way it can be unusable.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import threading
import types
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["ModelError", "ParametricModel", "cached_jacobian", "check_model", "load_model",
           "resolve_model", "restrict"]

#: Relative step of the central differences: the cube root of the machine epsilon balances
#: truncation and rounding errors.
FD_STEP = float(np.cbrt(np.finfo(float).eps))

_counter = itertools.count()
_cache: dict[tuple[str, int, int], ParametricModel] = {}
_by_text: dict[tuple[str, str], ParametricModel] = {}


class ModelError(ValueError):
    """A user's model that cannot be used; the message is one line naming the problem."""


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


@dataclass(frozen=True, eq=False, repr=False)
class ParametricModel:
    """A physics model ``f(theta; data)`` with named parameters (the contract above).

    Parameters
    ----------
    parameters : dict of str -> float or str
        Each parameter's start value, or the data column holding its per-row value.
    predict_fn : callable
        ``predict(params, data)``.
    jacobian_fn : callable, default=None
        ``jacobian(params, data)``; None: central finite differences.
    source : str, default="<model>"
        Where the model comes from (its file), as messages name it.
    text : str, default=None
        The model file's source code (:func:`load_model`'s models). Such a model is
        pickled as that text and imported again where it is unpickled: a fitted estimator
        (a logged MLflow model, a worker process) does not need the file.
    optional : tuple of str, default=()
        The parameters the model may lack (``OPTIONAL``), each with a number as its start.
    held : tuple of str, default=()
        The optional parameters held at their start values (:meth:`restricted`): they are
        not among :attr:`names`, ``theta`` has no column for them and the Jacobian no
        derivative.
    """

    parameters: dict[str, float | str]
    predict_fn: Callable[..., Any]
    jacobian_fn: Callable[..., Any] | None = None
    source: str = "<model>"
    text: str | None = None
    optional: tuple[str, ...] = ()
    held: tuple[str, ...] = ()

    def __reduce_ex__(self, protocol: Any) -> Any:
        """Pickle a model file's model as its source text, so it loads without the file."""
        if self.text is None:  # functions from Python: pickled as they are
            return object.__reduce_ex__(self, protocol)
        if self.held:
            return _held_from_text, (self.text, self.source, self.held)
        return _from_text, (self.text, self.source)

    def __copy__(self) -> ParametricModel:
        """The model itself (it is immutable)."""
        return self  # immutable: clone() keeps the one model (and its caches' keys)

    def __deepcopy__(self, memo: Any) -> ParametricModel:
        """The model itself (it is immutable)."""
        return self

    @classmethod
    def from_functions(cls, parameters: Mapping[str, float | str], predict: Callable[..., Any],
                       jacobian: Callable[..., Any] | None = None,
                       source: str = "<model>",
                       optional: Sequence[str] = ()) -> ParametricModel:
        """Build a model from a ``PARAMETERS`` dict and functions, checked as a file's are.

        Parameters
        ----------
        parameters : mapping of str to float or str
            Each parameter's start value, or the data column holding it per row.
        predict : callable
            ``predict(params, data)``: the prediction, ``(rows,)`` or ``(rows, targets)``.
        jacobian : callable, default=None
            ``jacobian(params, data)``: ``d predict / d params``, ``(rows, targets,
            parameters)`` (``None``: central finite differences).
        source : str, default="<model>"
            Where the model comes from, in messages.
        optional : sequence of str, default=()
            ``OPTIONAL``: the parameters the model may lack (held at their start values
            until a fit's covariates name them).

        Returns
        -------
        ParametricModel
            The model.

        Raises
        ------
        ModelError
            A ``PARAMETERS``, ``OPTIONAL`` or function that is not usable.
        """
        return _checked(dict(parameters) if isinstance(parameters, Mapping) else parameters,
                        predict, jacobian, source, optional=optional)

    def restricted(self, keep: Sequence[str]) -> ParametricModel:
        """The model with the optional parameters ``keep`` does not name held at their
        start values (the same model object for the same ``keep``).

        Parameters
        ----------
        keep : sequence of str
            The parameters to fit (every required one, and the optional ones to include).

        Returns
        -------
        ParametricModel
            The model whose :attr:`names` are ``keep``'s parameters in ``PARAMETERS``' order.
        """
        return _restricted(self, keep, lambda held: dataclasses.replace(self, held=held))

    def __repr__(self) -> str:
        """Name the model's source and parameters."""
        return f"ParametricModel({self.source!r}, parameters={self.names})"

    @property
    def names(self) -> list[str]:
        """The parameters fitted, in ``PARAMETERS``' order (all but the :attr:`held`)."""
        return [p for p in self.parameters if p not in self.held]

    def start(self, data: pd.DataFrame) -> np.ndarray:
        """Start values of every row, shape ``(rows, parameters)``.

        Parameters
        ----------
        data : pandas.DataFrame
            The rows (the columns a parameter takes its values from among them).

        Returns
        -------
        ndarray of shape (rows, parameters)
            The start values.

        Raises
        ------
        ModelError
            A column a parameter names is missing or not numeric.
        """
        n = len(data)
        out = np.empty((n, len(self.names)))
        for j, name in enumerate(self.names):
            value = self.parameters[name]
            if isinstance(value, str):
                if value not in data.columns:
                    raise ModelError(f"model {self.source}: parameter {name!r} takes its values "
                                     f"from column {value!r}, which the data lack; columns "
                                     f"are {[str(c) for c in data.columns]}")
                col = pd.to_numeric(data[value], errors="coerce").to_numpy(dtype=float)
                if not np.all(np.isfinite(col)):
                    raise ModelError(f"model {self.source}: column {value!r} (parameter "
                                     f"{name!r}) has missing or non-numeric values")
                out[:, j] = col
            else:
                out[:, j] = float(value)
        return out

    def _params(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        if not self.held:
            return {name: theta[:, j] for j, name in enumerate(self.parameters)}
        fitted = {name: theta[:, j] for j, name in enumerate(self.names)}
        return {name: fitted[name] if name in fitted
                else np.full(len(theta), float(self.parameters[name]))
                for name in self.parameters}

    def predict_rows(self, theta: np.ndarray, data: pd.DataFrame,
                     n_targets: int | None = None) -> np.ndarray:
        """The model at ``theta`` on every row, NaN or infinite where it returns them.

        :meth:`predict` without its check of the values: a fit's corrected parameters may
        leave the model's domain on some rows only (a negative lifetime under a square
        root), and the caller decides what those rows get. NumPy's floating-point warnings
        are silenced here.

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters.
        data : pandas.DataFrame
            The rows.
        n_targets : int, default=None
            The targets expected (``None``: any).

        Returns
        -------
        ndarray of shape (rows, targets)
            The prediction, possibly not finite on some rows.

        Raises
        ------
        ModelError
            One line: the model raises or returns the wrong shape.
        """
        n = len(data)
        try:
            with np.errstate(all="ignore"):
                out = self.predict_fn(self._params(theta), data)
                values = np.asarray(out, dtype=float)
        except Exception as exc:
            raise ModelError(f"model {self.source}: predict raised {_first_line(exc)}") from None
        if values.ndim == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[0] != n or (
                n_targets is not None and values.shape[1] != n_targets):
            want = "(rows,) or (rows, targets)" if n_targets is None else \
                f"({n},)" if n_targets == 1 else f"({n}, {n_targets})"
            raise ModelError(f"model {self.source}: predict returned shape "
                             f"{np.shape(out)}, expected {want} for {n} rows")
        return values

    def predict(self, theta: np.ndarray, data: pd.DataFrame,
                n_targets: int | None = None) -> np.ndarray:
        """The model's prediction at parameters ``theta`` (rows, parameters), shape
        ``(rows, targets)``; a :class:`ModelError` if it raises, has the wrong shape or is
        not finite.

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters.
        data : pandas.DataFrame
            The rows.
        n_targets : int, default=None
            The targets expected (``None``: any).

        Returns
        -------
        ndarray of shape (rows, targets)
            The prediction.
        """
        n = len(data)
        values = self.predict_rows(theta, data, n_targets)
        bad = ~np.isfinite(values).all(axis=1)
        if bad.any():
            raise ModelError(f"model {self.source}: predict returned NaN or infinite values "
                             f"on {int(bad.sum())} of {n} rows (first rows: "
                             f"{np.flatnonzero(bad)[:5].tolist()})")
        return values

    def jacobian(self, theta: np.ndarray, data: pd.DataFrame, n_targets: int) -> np.ndarray:
        """``d predict / d theta``, shape ``(rows, targets, parameters)``: the model's own
        ``jacobian`` or central finite differences (step :data:`FD_STEP` times each value,
        at least a thousandth of the parameter's mean magnitude over the rows).

        Parameters
        ----------
        theta : ndarray of shape (rows, parameters)
            The parameters.
        data : pandas.DataFrame
            The rows.
        n_targets : int
            The prediction's targets.

        Returns
        -------
        ndarray of shape (rows, targets, parameters)
            The Jacobian.
        """
        n, P = theta.shape
        if self.jacobian_fn is not None:
            try:
                jac = np.asarray(self.jacobian_fn(self._params(theta), data), dtype=float)
            except Exception as exc:
                raise ModelError(f"model {self.source}: jacobian raised "
                                 f"{_first_line(exc)}") from None
            every = len(self.parameters)  # the file's jacobian: every parameter's column
            if n_targets == 1 and jac.shape == (n, every):
                jac = jac[:, None, :]
            if jac.shape != (n, n_targets, every):
                raise ModelError(f"model {self.source}: jacobian returned shape {jac.shape}, "
                                 f"expected (rows, targets, parameters) = ({n}, {n_targets}, "
                                 f"{every})")
            if self.held:
                jac = jac[:, :, [j for j, p in enumerate(self.parameters)
                                 if p not in self.held]]
            if not np.all(np.isfinite(jac)):
                raise ModelError(f"model {self.source}: jacobian returned NaN or infinite "
                                 "values")
            return jac
        scale = np.abs(theta).mean(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        jac = np.empty((n, n_targets, P))
        for p in range(P):
            h = FD_STEP * np.maximum(np.abs(theta[:, p]), 1e-3 * scale[p])
            up, down = theta.copy(), theta.copy()
            up[:, p] += h
            down[:, p] -= h
            h = up[:, p] - down[:, p]  # the steps actually taken (rounding)
            jac[:, :, p] = (self.predict(up, data, n_targets)
                            - self.predict(down, data, n_targets)) / h[:, None]
        return jac


#: Jacobians of recent (model, data, parameters): a forward selection refits every candidate
#: from the same coefficients on each fold, so each fit's first Jacobian is the same.
_JACOBIANS: OrderedDict[tuple[int, int, int, bytes], tuple[Any, Any, np.ndarray]] = \
    OrderedDict()
_JACOBIANS_KEPT = 64
#: Guards the module's caches (:func:`cached_jacobian`, :func:`_restricted`).
_CACHE_LOCK = threading.RLock()


def cached_jacobian(model: ParametricModel, theta: np.ndarray, data: pd.DataFrame,
                    n_targets: int) -> np.ndarray:
    """Return :meth:`ParametricModel.jacobian`, remembered for the last few calls.

    The calls are keyed by the model and data objects (which the cache holds) and the
    parameters' values.

    Parameters
    ----------
    model : ParametricModel
        The model.
    theta : ndarray of shape (rows, parameters)
        The parameters.
    data : DataFrame
        The rows.
    n_targets : int
        The prediction's targets.

    Returns
    -------
    ndarray of shape (rows, targets, parameters)
        The Jacobian.
    """
    # the parameters to about 13 significant digits: a fit warm-started from another's
    # coefficients computes them in another order of summation
    key = (id(model), id(data), n_targets, (np.ascontiguousarray(theta).view(np.int64)
                                            >> 8).tobytes())
    with _CACHE_LOCK:  # the linearised selection fits folds on threads
        hit = _JACOBIANS.get(key)
        if hit is not None and hit[0] is model and hit[1] is data:
            _JACOBIANS.move_to_end(key)
            return hit[2]
    jac = model.jacobian(theta, data, n_targets)
    with _CACHE_LOCK:
        _JACOBIANS[key] = (model, data, jac)
        while len(_JACOBIANS) > _JACOBIANS_KEPT:
            _JACOBIANS.popitem(last=False)
    return jac


def _restricted(model: Any, keep: Sequence[str], build: Callable[[tuple[str, ...]], Any]) -> Any:
    """``model`` with its optional parameters outside ``keep`` held (``build(held)``),
    one object per (model, held): the Jacobian cache and the selection's warm starts key on
    it."""
    kept = set(keep)
    every = list(model.parameters)
    unknown = sorted(kept - set(every))
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown}; the model's parameters are {every}")
    required = [p for p in every if p not in model.optional and p not in kept]
    if required:
        raise ValueError(f"parameter(s) {required} are not optional: only the model's "
                         f"optional parameters {list(model.optional)} can be held")
    held = tuple(p for p in model.optional if p not in kept)
    if held == tuple(getattr(model, "held", ())):
        return model
    key = (id(model), held)
    with _CACHE_LOCK:  # one object per (model, held), also across threads
        hit = _RESTRICTED.get(key)
        if hit is not None and hit[0] is model:
            return hit[1]
        out = build(held)
        _RESTRICTED[key] = (model, out)
        while len(_RESTRICTED) > _RESTRICTED_KEPT:
            _RESTRICTED.popitem(last=False)
    return out


#: :func:`_restricted`'s models: (id of the model, held) -> (the model, the restricted one).
_RESTRICTED: OrderedDict[tuple[int, tuple[str, ...]], tuple[Any, Any]] = OrderedDict()
_RESTRICTED_KEPT = 256


def restrict(model: Any, keep: Sequence[str]) -> Any:
    """``model`` fitting the parameters ``keep`` names: its optional parameters outside
    ``keep`` held at their start values (a model without optional parameters as it is).

    Parameters
    ----------
    model : ParametricModel or model object
        The model (a model object without ``optional`` has none).
    keep : sequence of str
        The parameters to fit.

    Returns
    -------
    ParametricModel or model object
        The model whose :attr:`names` are ``keep``'s parameters.
    """
    if not getattr(model, "optional", ()):
        return model
    return model.restricted(keep)


def _checked(parameters: Any, predict: Any, jacobian: Any, source: str,
             text: str | None = None, optional: Any = ()) -> ParametricModel:
    """A :class:`ParametricModel` from the contract's objects, each checked."""
    if not isinstance(parameters, dict) or not parameters:
        raise ModelError(f"model {source}: PARAMETERS must be a non-empty dict from each "
                         f"parameter's name to its start value or a data column, got "
                         f"{type(parameters).__name__}")
    for name, value in parameters.items():
        if not isinstance(name, str) or not name:
            raise ModelError(f"model {source}: PARAMETERS' keys must be names (str), got "
                             f"{name!r}")
        if isinstance(value, bool) or not isinstance(value, (int, float, str)) or (
                not isinstance(value, str) and not np.isfinite(value)):
            raise ModelError(f"model {source}: PARAMETERS[{name!r}] must be a finite number "
                             f"(its start value) or a column name, got {value!r}")
    if not callable(predict):
        raise ModelError(f"model {source}: predict must be a function predict(params, data)")
    if jacobian is not None and not callable(jacobian):
        raise ModelError(f"model {source}: jacobian must be a function jacobian(params, data)")
    if isinstance(optional, str) or not isinstance(optional, (list, tuple)):
        raise ModelError(f"model {source}: OPTIONAL must be a list of parameter names, got "
                         f"{type(optional).__name__}")
    for name in optional:
        if name not in parameters:
            raise ModelError(f"model {source}: OPTIONAL names {name!r}, not a parameter; the "
                             f"parameters are {list(parameters)}")
        if isinstance(parameters[name], str):
            raise ModelError(f"model {source}: OPTIONAL parameter {name!r} must start at a "
                             f"number (it is held there until fitted), not column "
                             f"{parameters[name]!r}")
    if len(set(optional)) == len(parameters):
        raise ModelError(f"model {source}: every parameter is OPTIONAL; at least one must "
                         "be fitted always")
    values = {k: v if isinstance(v, str) else float(v) for k, v in parameters.items()}
    return ParametricModel(values, predict, jacobian, source, text,
                           tuple(dict.fromkeys(optional)))


def _from_text(text: str, source: str) -> ParametricModel:
    """Import a model file's source code ``text`` (once per process), as :func:`load_model`.

    ``source`` names the file in messages (and is the module's ``__file__``).
    """
    key = (source, text)
    if key in _by_text:
        return _by_text[key]
    module = types.ModuleType(f"workbench_user_model_{next(_counter)}")
    module.__file__ = source
    try:
        exec(compile(text, source, "exec"), module.__dict__)  # the user's model file
    except Exception as exc:  # the user's code: anything
        raise ModelError(f"model file {source} does not import: {_first_line(exc)}") from None
    for required in ("PARAMETERS", "predict"):
        if not hasattr(module, required):
            raise ModelError(f"model file {source} defines no {required} (a model file defines "
                             "PARAMETERS, predict(params, data) and optionally "
                             "jacobian(params, data))")
    model = _checked(module.PARAMETERS, module.predict, getattr(module, "jacobian", None),
                     source, text, getattr(module, "OPTIONAL", ()))
    _by_text[key] = model
    return model


def _held_from_text(text: str, source: str, held: tuple[str, ...]) -> ParametricModel:
    """Unpickle a model file's model with parameters held (:meth:`ParametricModel.restricted`)."""
    model = _from_text(text, source)
    return model.restricted([p for p in model.parameters if p not in held])


def load_model(path: str | os.PathLike[str]) -> ParametricModel:
    """Import a model file (see the module's docstring) and check its definitions.

    A file is imported once per process while it is unchanged (size and modification time).

    Parameters
    ----------
    path : str or path-like
        The model file.

    Returns
    -------
    ParametricModel
        Its model.

    Raises
    ------
    ModelError
        One line: the file is missing or does not import, or lacks ``PARAMETERS`` or
        ``predict``, or they are of the wrong kind.
    """
    file = Path(path).expanduser().resolve()
    if not file.is_file():
        raise ModelError(f"model file {path} not found")
    stat = file.stat()
    key = (str(file), stat.st_mtime_ns, stat.st_size)
    if key in _cache:
        return _cache[key]
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"model file {path} does not import: {_first_line(exc)}") from None
    model = _from_text(text, str(path))
    _cache[key] = model
    return model


#: What a model object has (:class:`ParametricModel`'s interface; the parameter-space engine
#: and the parametric regressors use nothing else).
_INTERFACE = ("names", "parameters", "source", "start", "predict", "jacobian")


def resolve_model(model: Any) -> ParametricModel:
    """Return a :class:`ParametricModel` from a model or the path of a model file.

    Parameters
    ----------
    model : ParametricModel, model object, str or path-like
        The model (or any object with its interface: ``names``, ``parameters``,
        ``source``, ``start``, ``predict`` and ``jacobian``, as
        :class:`workbench.hamiltonian.HamiltonianModel`), or its file.

    Returns
    -------
    ParametricModel
        The model.
    """
    if isinstance(model, ParametricModel) or all(
            hasattr(model, name) for name in _INTERFACE):
        return model  # a model object, e.g. workbench.hamiltonian.HamiltonianModel
    if isinstance(model, (str, os.PathLike)):
        return load_model(model)
    raise ModelError("model must be the path of a model file or a ParametricModel, got "
                     f"{type(model).__name__}")


def check_model(model: ParametricModel, data: pd.DataFrame, n_targets: int | None = None,
                theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Evaluate ``model`` on ``data`` at ``theta`` (default: its start values) and check it.

    Parameters
    ----------
    model : ParametricModel
        The model.
    data : DataFrame
        The rows.
    n_targets : int, default=None
        The targets the prediction must have (None: any).
    theta : ndarray of shape (rows, parameters), default=None
        The parameters (None: the start values).

    Returns
    -------
    prediction : ndarray of shape (rows, targets)
        The model's prediction at ``theta``.
    jacobian : ndarray of shape (rows, targets, parameters)
        Its derivatives with respect to the parameters.

    Raises
    ------
    ModelError
        One line: the model raises, returns NaN or the wrong shape, its Jacobian has the
        wrong shape, or a parameter's derivative is zero on every row.
    """
    theta = model.start(data) if theta is None else theta
    value = model.predict(theta, data, n_targets)
    jac = cached_jacobian(model, theta, data, value.shape[1])
    flat = np.abs(jac).max(axis=(0, 1))
    dead = [name for name, m in zip(model.names, flat) if not m > 0]
    if dead:
        raise ModelError(f"model {model.source}: the prediction does not depend on parameter"
                         f"{'s' if len(dead) > 1 else ''} {', '.join(map(repr, dead))} (its "
                         "derivative is zero on every row)")
    return value, jac
