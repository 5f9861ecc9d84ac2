"""Generate ``reference/config.md``, the config reference, from the typed config schemas.

Every table of a config file and every key of it, with its type, default, constraints and
meaning, is read from the pydantic models of :mod:`workbench.experiment.config` (and a model
family's own ``[model.<family>]`` schema): the meaning from the schema's numpydoc
``Parameters`` section. So the page cannot drift from the code:
``tests/test_docs.py`` compares the schemas' fields with the page this writes.
"""

from __future__ import annotations

import inspect
import re
import types
import typing
from typing import Any

from pydantic import BaseModel
from pydantic.fields import FieldInfo

#: Per table, the keys that are tables of their own (each rendered under its own heading).
NESTED = {
    "(top level)": {"data", "model", "selection", "evaluation", "intervals", "search", "cv",
                    "study", "tracking"},
    "[data]": {"hamiltonian"},
    "[model]": {"targets"},
}


def sections() -> list[tuple[str, type[BaseModel], str]]:
    """The config's tables in file order: ``(table, schema, note)``."""
    from workbench.experiment import config as c
    from workbench.experiment.families import FAMILIES, discover_families

    discover_families()
    out: list[tuple[str, type[BaseModel], str]] = [
        ("(top level)", c.TopLevel, "The keys before the first table."),
        ("[data]", c.DataConfig, ""),
        ("[data.hamiltonian]", c.HamiltonianData, "Optional; for the physics-aware families."),
        ("[model]", c.ModelConfig,
         "A key left out takes the default shown in brackets (the paper's settings, "
         "`MODEL_DEFAULTS`)."),
        ("[model.targets.<target>]", c.BoostSettings,
         "Per-target overrides of `[model]`'s boosting settings; every key optional."),
    ]
    for name in sorted(FAMILIES):
        settings = FAMILIES[name].settings
        if settings is not None:
            out.append((f"[model.{name}]", settings,
                        f"The settings of family `{name}` (`[model] family = \"{name}\"`); "
                        f"`[search.{name}]` varies them in a sweep."))
    out += [
        ("[selection]", c.SelectionConfig, ""),
        ("[evaluation]", c.EvaluationConfig, ""),
        ("[intervals]", c.IntervalsConfig, ""),
        ("[cv]", c.CVConfig, ""),
        ("[study]", c.StudyConfig, ""),
        ("[tracking]", c.TrackingConfig, ""),
    ]
    return out


def keys(schema: type[BaseModel], table: str) -> list[str]:
    """The keys of ``schema`` that the page lists under ``table`` (not the nested tables)."""
    return [k for k in schema.model_fields if k not in NESTED.get(table, set())]


def type_name(annotation: Any) -> str:
    """A field's type as a reader writes it: ``int``, ``str or list of str``, ``"a" | "b"``."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return type_name(args[0])
    if origin in (typing.Union, types.UnionType):
        parts = [type_name(a) for a in args if a is not type(None)]
        text = " or ".join(dict.fromkeys(parts))
        return text + (" or none" if type(None) in args else "")
    if origin is typing.Literal:
        return " \\| ".join(repr(a).replace("'", '"') for a in args)
    if origin in (list, tuple):
        return f"list of {type_name(args[0])}" if args else "list"
    if origin is dict:
        return "table"
    if inspect.isclass(annotation) and issubclass(annotation, BaseModel):
        return "table"
    return getattr(annotation, "__name__", str(annotation))


def constraints(info: FieldInfo) -> str:
    """The bounds pydantic checks (``>= 1, <= 10000``) and the estimator that checks the rest."""
    out = []
    for meta in info.metadata:
        for attr, sign in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
            value = getattr(meta, attr, None)
            if value is not None:
                out.append(f"{sign} {value:,}" if isinstance(value, int) else f"{sign} {value}")
    checked = _checked_by(info.annotation) or _checked_by(typing.Annotated[Any, *info.metadata]
                                                          if info.metadata else None)
    if checked:
        out.append(f"checked by `{checked}`")
    return ", ".join(out)


def _checked_by(annotation: Any) -> str | None:
    from workbench.experiment.config.schema import ParameterOf

    for arg in typing.get_args(annotation):
        if isinstance(arg, ParameterOf):
            return arg.estimator.__name__
        found = _checked_by(arg)
        if found:
            return found
    return None


def default(info: FieldInfo, key: str, table: str) -> str:
    """The default as TOML would write it (``required`` when there is none)."""
    if info.is_required():
        return "required"
    value = info.get_default(call_default_factory=True)
    if table == "[model]" and value is None:
        from workbench.experiment.config import MODEL_DEFAULTS

        if key in MODEL_DEFAULTS:
            return f"({_toml(MODEL_DEFAULTS[key])})"
    return _toml(value)


def _toml(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    return repr(value)


def _markdown(text: str) -> str:
    """reST on one line as MyST-friendly Markdown: roles and literals as code."""
    text = " ".join(text.split())
    return re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text).replace("``", "`")


def _summary(schema: type[BaseModel]) -> str:
    doc = inspect.getdoc(schema) or ""
    return _markdown(doc.split("\n\n")[0])


def meanings(schema: type[BaseModel]) -> dict[str, str]:
    """Each key's entry in the schema's ``Parameters`` section, as one line of Markdown.

    An entry that points elsewhere (``As in :class:`BoostSettings```) is taken from the
    first base class that documents the key itself.
    """
    from numpydoc.docscrape import NumpyDocString

    out: dict[str, str] = {}
    for cls in schema.__mro__:
        if not (inspect.isclass(cls) and issubclass(cls, BaseModel)) or not cls.__doc__:
            continue
        for entry in NumpyDocString(inspect.getdoc(cls) or "")["Parameters"]:
            text = " ".join(entry.desc)
            if text.startswith("As in "):
                continue
            for key in entry.name.split(","):
                out.setdefault(key.strip(), _markdown(text).replace("|", "\\|"))
    return out


def render() -> str:
    """The page: one table per config table, one row per key."""
    lines = ["# Config reference", "",
             "Every table and key of an experiment config (a TOML file), generated from the "
             "typed schemas of `workbench.experiment.config` when the documentation is built. "
             "Unknown keys are an error listing the valid ones. A key *checked by* an "
             "estimator has its value checked against that estimator's "
             "`_parameter_constraints` when the config is loaded. `[search]` is described "
             "in the [sweeps guide](../user_guide/sweeps.md): its keys are the keys of "
             "`[model]` (and `[search.<family>]` those of `[model.<family>]`), each a list "
             "(a choice), a `{ low, high, log }` range or a fixed value.", ""]
    for table, schema, note in sections():
        lines += [f"## `{table}`", "", _summary(schema), ""]
        if note:
            lines += [note, ""]
        lines += ["| key | type | default | constraints | meaning |", "|---|---|---|---|---|"]
        meaning = meanings(schema)
        for key in keys(schema, table):
            info = schema.model_fields[key]
            lines.append(f"| `{key}` | {type_name(info.annotation)} | "
                         f"`{default(info, key, table)}` | {constraints(info)} | "
                         f"{meaning.get(key, '')} |")
        lines.append("")
    return "\n".join(lines)


def setup(app: Any) -> dict[str, Any]:
    """Register the page's generation at the start of every build."""
    from generated_page import connect  # docs/_ext, on the path conf.py sets

    return connect(app, "config.md", render)
