"""``workbench init``: a first config for a CSV of your own.

The config's ``[data]`` section is written from the command's options; everything after it
(``[model]``, ``[selection]``, ...) is the text of one template, the package data file
``workbench/experiment/templates/generic.toml``, copied with its comments. First the data
are loaded as ``workbench evaluate`` will load them (same loader, values and one-line
errors) and the config is parsed by the project's parser; then it is written all or nothing.
The CSV is read from disk once (:func:`~workbench.datasets.read_once`), however many of
these steps look at it.
"""

from __future__ import annotations

import os
import shlex
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

from ...datasets import load_csv_dataset, read_once
from ..config import load_dataset
from ..config.toml_text import split_template, toml_comment, toml_string, toml_strings
from ..process.errors import ConfigError, UsageError
from ..process.outputs import check_file, write_file
from ..splits.columns import OrderColumn, find_order_column, group_columns, numeric_columns
from .prepare import parse_config

__all__ = ["DEFAULT_TEST_FRACTION", "TEMPLATE", "InitResult", "csv_entry", "init_config",
           "render_config", "template_text"]

#: The template every generated config copies below its ``[data]`` section.
TEMPLATE = "generic.toml"
#: The template of a config whose prior is a model file (``--model``).
PARAMETRIC_TEMPLATE = "parametric.toml"
#: The share of rows held out for testing when no split column is given.
DEFAULT_TEST_FRACTION = 0.3
#: The keys the command writes itself; the template may not set them.
_OWN_KEYS = ("name", "random_state", "data")


@dataclass(frozen=True)
class InitResult:
    """What :func:`init_config` wrote.

    Parameters
    ----------
    path : Path
        The config file.
    text : str
        Its text.
    features : list of str
        The feature columns it names.
    defaulted : bool
        Whether the features were chosen by default (every other numeric column).
    skipped : dict of str to str
        When defaulted: the columns not taken, with the reason.
    n_train, n_test : int
        The split's sizes.
    group_hints : dict of str to int
        Without a group column: text columns whose values repeat (e.g. a device or a date),
        with their number of distinct values: candidates for ``--group-column``.
    order : OrderColumn, default=None
        The column the CV folds chain forward by (``[data] order_column``), found or given.
    time_split : bool, default=False
        Whether the test rows are the latest ones by ``order`` (``split = "time"``).
    """

    path: Path
    text: str
    features: list[str]
    defaulted: bool
    skipped: dict[str, str] = field(default_factory=dict)
    n_train: int = 0
    n_test: int = 0
    #: Without a group column: text columns whose values repeat (e.g. a device or a date),
    #: with their number of distinct values: candidates for ``--group-column``.
    group_hints: dict[str, int] = field(default_factory=dict)
    order: OrderColumn | None = None
    time_split: bool = False


def template_text(name: str = TEMPLATE) -> str:
    """Read a config template shipped with the package.

    Package data, read through :mod:`importlib.resources`: an installed wheel carries it.

    Parameters
    ----------
    name : str, default=TEMPLATE
        The template's file name under ``workbench/experiment/templates/``.

    Returns
    -------
    str
        Its text.
    """
    source = resources.files("workbench.experiment") / "templates" / name
    return source.read_text(encoding="utf-8")


def csv_entry(csv: str | os.PathLike[str], config: str | os.PathLike[str]) -> str:
    """Write the ``[data] csv`` entry for the file ``csv`` in the config ``config``.

    Parameters
    ----------
    csv : path-like
        The data file.
    config : path-like
        The config file that will name it.

    Returns
    -------
    str
        The path relative to the config's directory (as the config parser reads it), or
        absolute where no relative path leads there (another drive); forward slashes, which
        every platform reads.
    """
    target = Path(csv).resolve()
    base = Path(config).resolve().parent
    try:
        return Path(os.path.relpath(target, base)).as_posix()
    except ValueError:  # Windows: the file and the config on different drives
        return target.as_posix()


def render_config(*, name: str, csv: str, prior: Sequence[str], targets: Sequence[str],
                  features: Sequence[str], split_column: str | None, test_fraction: float | None,
                  split_seed: int, out: str, source: str, template: str,
                  group_column: str | None = None, order_column: str | None = None,
                  time_split: bool = False, section: str | None = None) -> str:
    """Write the config's text.

    A header comment (what wrote it, from which CSV, what to run next), ``name``,
    ``random_state``, ``[data]``, then the ``template``'s text as is (top-level keys of the
    template, if any, above ``[data]``: :func:`~.toml_text.split_template`).

    Parameters
    ----------
    name : str
        The data set's name.
    csv : str
        The ``[data] csv`` entry (:func:`csv_entry`).
    prior, targets, features : sequence of str
        The columns of ``[data]``.
    split_column : str or None
        The train/test column, or ``None`` for a random split.
    test_fraction : float or None
        The random split's test share (when ``split_column`` is ``None``).
    split_seed : int
        The random split's seed.
    out : str
        The config's path, for the header's next command.
    source : str
        Where the CSV came from, for the header.
    template : str
        The template's text.
    group_column : str, default=None
        The column whose groups CV folds keep whole.
    order_column : str, default=None
        The column the CV folds chain forward by (dates, times, run numbers).
    time_split : bool, default=False
        The test rows are the latest ``test_fraction`` by ``order_column``.
    section : str, default=None
        The model file's table (``--model``), after the template's; ``prior`` is then empty.

    Returns
    -------
    str
        The config's text.
    """
    header = [
        f"# A first config for the data set {toml_comment(repr(name))}, written by `workbench "
        f"init` from {toml_comment(source)}.",
        "# [data] names the CSV's columns (its csv path is relative to this file); the sections",
        f"# after it are the template {TEMPLATE if section is None else PARAMETRIC_TEMPLATE} "
        "(workbench/experiment/templates/), to edit.",
        "# Next:",
        f"#   workbench evaluate {toml_comment(shlex.quote(out))}",
        "#   workbench ui",
    ]
    data = [
        "[data]",
        f"csv = {toml_string(csv)}",
        *(["# one prior column per target, in the same order", toml_strings("prior", prior)]
          if section is None else ["# no prior columns: the model file of [model.parametric] "
                                   "is the prior"]),
        toml_strings("targets", targets),
        "# the basis' inputs besides the prior",
        toml_strings("features", features),
    ]
    if split_column is not None:
        data.append(f"split_column = {toml_string(split_column)}   # its values: train, test")
    elif time_split:
        data += [f"test_fraction = {test_fraction!r}   # the latest rows by order_column",
                 'split = "time"']
    else:
        assert test_fraction is not None  # one of the two (init_config)
        data += [f"test_fraction = {test_fraction!r}   # of the rows, drawn at random with "
                 "split_seed", f"split_seed = {split_seed}"]
    if group_column is not None:
        data.append(f"group_column = {toml_string(group_column)}"
                    "   # CV folds keep each group whole")
    if order_column is not None:
        data.append(f"order_column = {toml_string(order_column)}"
                    "   # CV folds chain forward: each trains on earlier rows")
    top, rest = split_template(template)
    head = [*header, "", f"name = {toml_string(name)}", "random_state = 0"]
    return "\n".join(head) + "\n" + (top and top.rstrip("\n") + "\n") + "\n" \
        + "\n".join(data) + "\n\n" + rest + (section or "")


def _check_template(template: str) -> dict[str, Any]:
    """Return the template's tables; it must be valid TOML and leave the keys init writes alone."""
    try:
        tables = tomllib.loads(template)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"template {TEMPLATE}: not valid TOML: {exc}") from None
    own = [key for key in _OWN_KEYS if key in tables]
    if own:
        raise ConfigError(f"template {TEMPLATE} sets {own}: workbench init writes them")
    return tables


def _parse(text: str, template: dict[str, Any], own: Sequence[str] = ()) -> dict[str, Any]:
    """Read the generated text back and check it against the template.

    Its keys beyond init's own must be the template's, unchanged (the last guard of
    :func:`~.toml_text.split_template`).
    """
    raw = tomllib.loads(text)
    rest = {k: v for k, v in raw.items() if k not in _OWN_KEYS}
    if own:  # [model.<own>]: written by init, not the template's
        rest["model"] = {k: v for k, v in rest.get("model", {}).items() if k not in own}
    if rest != template:
        raise ConfigError(f"template {TEMPLATE}: its settings change when written below "
                          f"[data] (keys before its first table?)")
    return raw


def _features(path: Path, prior: list[str], targets: list[str], features: Sequence[str] | None,
              split_column: str | None, group_column: str | None, order_column: str | None
              ) -> tuple[list[str], dict[str, str], dict[str, int]]:
    """Choose the feature columns, and the candidates for a group column.

    The features as given, or every other numeric column (with the columns skipped and why);
    group candidates (not the order column) only without a group column.
    """
    skipped: dict[str, str] = {}
    roles = [*prior, *targets, *(c for c in (split_column, order_column) if c)]
    hints = {} if group_column else group_columns(path, roles)  # (--group-column: no order)
    if features is None:
        features, skipped = numeric_columns(
            path, [*roles, *([group_column] if group_column else [])])
    return list(features), skipped, hints


def _checked_order(path: Path, *, order_column: str | None, group_column: str | None,
                   **options: Any) -> str | None:
    """Load the data as the config will, then choose the order column.

    The loader's checks and messages first; then the column given, or the one found
    (``"auto"``, without a group column), or none.
    """
    given = None if order_column == "auto" else order_column
    load_csv_dataset(path, group_column=group_column, order_column=given, **options)
    if order_column == "auto" and group_column is None:
        found = find_order_column(path, [*options["prior"], *options["targets"],
                                         options["split_column"] or ""])
        given = found.column if found is not None else None
    return given


def _prior_or_model(prior: Sequence[str] | None, model: str | os.PathLike[str] | None,
                    out: Path) -> tuple[list[str], str | None]:
    """Return the prior columns, or the model file's table of the config (file checked)."""
    if (model is None) == (not prior):
        raise UsageError("give either --prior (the model's predictions, columns) or --model "
                         "(the model itself, a Python file)")
    if model is None:
        return list(prior or []), None
    from ..families.parametric import config_section

    try:
        return [], config_section(csv_entry(model, out), model)
    except ConfigError as exc:
        raise UsageError(f"--model: {exc}") from None


def _split_options(split_column: str | None, test_fraction: float | None,
                   split_seed: int | None) -> tuple[float | None, int | None]:
    """Check the split's options; return the test fraction and seed (defaults filled in)."""
    if split_column is not None:
        if test_fraction is not None:
            raise UsageError("give either --split-column or --test-fraction, not both")
        if split_seed is not None:
            raise UsageError("--split-seed draws the random split of --test-fraction; "
                             "--split-column gives the split")
        return None, None
    return (DEFAULT_TEST_FRACTION if test_fraction is None else test_fraction,
            0 if split_seed is None else split_seed)


def _output(name: str, out: str | os.PathLike[str] | None, force: bool) -> Path:
    """Check ``--name`` and choose the config file to write (``<name>.toml`` by default)."""
    if not name.strip():
        raise UsageError("--name: give a non-empty name")
    if out is None:
        if any(sep in name for sep in "/\\"):
            raise UsageError(f"--name {name!r} holds a path separator: give --out too")
        out = f"{name}.toml"
    path = check_file(out, "--out")  # a file name, in a folder that can be written
    if path.exists() and not force:
        raise UsageError(f"{path} exists: nothing written (--force overwrites it)")
    return path


def init_config(csv: str | os.PathLike[str], *, prior: Sequence[str] | None,
                targets: Sequence[str], features: Sequence[str] | None = None,
                split_column: str | None = None,
                test_fraction: float | None = None, split_seed: int | None = None,
                name: str | None = None, out: str | os.PathLike[str] | None = None,
                force: bool = False, group_column: str | None = None,
                order_column: str | None = "auto",
                model: str | os.PathLike[str] | None = None) -> InitResult:
    """Write a first config for the CSV ``csv`` and return what was written.

    Parameters
    ----------
    csv : path-like
        The data file.
    prior, targets : sequence of str
        One prior column per target, and the targets, in the same order.
    features : sequence of str, default=None
        The basis' inputs; ``None`` takes every other numeric column (not the prior, target
        and split columns, nor ``group_column``).
    split_column : str, default=None
        A column of ``train``/``test`` values giving the split.
    test_fraction : float, default=None
        Without ``split_column``: the random split's test share
        (:data:`DEFAULT_TEST_FRACTION` when ``None``).
    split_seed : int, default=None
        The random split's seed (0 when ``None``; given: random with an order column too).
    name : str, default=None
        The data set's name; the CSV's stem when ``None``.
    out : path-like, default=None
        The config to write; ``<name>.toml`` when ``None``.
    force : bool, default=False
        Overwrite an existing ``out``.
    group_column : str, default=None
        Each row's group (e.g. its device), kept whole by the CV folds.
    order_column : str, default="auto"
        The column of dates or run numbers the CV folds chain forward by, the latest rows
        the test rows; ``"auto"``: :func:`~.columns.find_order_column`; ``None``: none.
    model : path-like, default=None
        A model file (``PARAMETERS``, ``predict``, optionally ``jacobian``: see
        :mod:`workbench.parametric`) instead of ``prior`` columns: the config's family is then
        ``parametric``, the model the prior.

    Returns
    -------
    InitResult
        What was written.

    Raises
    ------
    UsageError
        Contradictory options, or an existing ``out`` without ``force``.
    DatasetError
        Bad data, as ``workbench evaluate`` would report them; nothing is written then.
    ConfigError
        A template that does not combine with the generated ``[data]``.
    """
    with read_once():  # the loader's checks, the columns proposed, the config's own load
        return _init_config(csv, prior=prior, targets=targets, features=features,
                            split_column=split_column, test_fraction=test_fraction,
                            split_seed=split_seed, name=name, out=out, force=force,
                            group_column=group_column, order_column=order_column, model=model)


def _init_config(csv: str | os.PathLike[str], *, prior: Sequence[str] | None,
                 targets: Sequence[str], features: Sequence[str] | None,
                 split_column: str | None, test_fraction: float | None,
                 split_seed: int | None, name: str | None,
                 out: str | os.PathLike[str] | None, force: bool, group_column: str | None,
                 order_column: str | None,
                 model: str | os.PathLike[str] | None) -> InitResult:
    """Write the config of :func:`init_config` (its CSV read once by the caller's block)."""
    csv = Path(csv)
    name = csv.stem if name is None else name
    out = _output(name, out, force)
    random_split = split_seed is not None
    test_fraction, split_seed = _split_options(split_column, test_fraction, split_seed)
    prior, section = _prior_or_model(prior, model, out)
    targets = list(targets)
    entry = csv_entry(csv, out)
    path = (out.parent / entry).resolve()  # where load_dataset will read it
    given = _checked_order(path, prior=prior, targets=targets, features=features or (),
                           test_fraction=test_fraction, split_column=split_column, name=name,
                           split_seed=split_seed or 0, group_column=group_column,
                           order_column=order_column)
    time_split = given is not None and split_column is None and not random_split
    defaulted = features is None
    features, skipped, hints = _features(path, prior, targets, features, split_column,
                                         group_column, given)
    template = template_text() if model is None else template_text(PARAMETRIC_TEMPLATE)
    tables = _check_template(template)
    text = render_config(name=name, csv=entry, prior=prior, targets=targets, features=features,
                         split_column=split_column, test_fraction=test_fraction,
                         split_seed=split_seed or 0, out=str(out), source=str(csv),
                         template=template, group_column=group_column, order_column=given,
                         time_split=time_split, section=section)
    # the project's own parser
    cfg = parse_config(_parse(text, tables, ("parametric",) if model else ()), out)
    dataset = load_dataset(cfg)  # exactly what evaluate loads, its size checks included
    write_file(out, text, "--out")  # atomic_write: all or nothing, a failure in one line
    return InitResult(path=out, text=text, features=features, defaulted=defaulted,
                      skipped=skipped, n_train=len(dataset.train_index),
                      n_test=len(dataset.test_index), group_hints=hints,
                      order=None if dataset.order is None else OrderColumn.of(dataset.order),
                      time_split=time_split)
