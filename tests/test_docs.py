"""The documentation (docs/, ``make docs``) cannot go stale.

The config reference lists every key of every section of the typed schemas, the CLI
reference every option of every command, the API reference only modules and names that
exist; and the site builds with warnings as errors (the gallery not run: ``make docs`` runs
it), with no broken internal link and nothing fetched from the web but MathJax.
"""

import importlib
import importlib.util
import inspect
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from pydantic import BaseModel

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _extension(name):
    spec = importlib.util.spec_from_file_location(f"docs_{name}", DOCS / "_ext" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _tables(page):
    """``{heading: [first-column cells]}`` of a generated Markdown page."""
    out, current = {}, None
    for line in page.splitlines():
        heading = re.match(r"## `(.+)`$", line)
        if heading:
            current = out.setdefault(heading.group(1), [])
        elif current is not None and line.startswith("| `"):
            current.append(line.split("`")[1])
    return out


def _expected_config_keys():
    """Every (table, key) a config file may hold, walked from the schemas themselves."""
    from workbench.experiment import config as c
    from workbench.experiment.families import FAMILIES, discover_families

    def fields(model, skip=()):
        return {k for k in model.model_fields if k not in skip}

    sections = {name: info.annotation for name, info in c.TopLevel.model_fields.items()
                if inspect.isclass(info.annotation) and issubclass(info.annotation, BaseModel)}
    expected = {"(top level)": {k for k in fields(c.TopLevel)
                                if k not in sections and k not in ("data", "model", "search")},
                "[data]": fields(c.DataConfig, {"hamiltonian"}),
                "[data.hamiltonian]": fields(c.HamiltonianData),
                "[model]": fields(c.ModelConfig, {"targets"}),
                "[model.targets.<target>]": fields(c.BoostSettings)}
    expected.update({f"[{name}]": fields(model) for name, model in sections.items()})
    discover_families()
    expected.update({f"[model.{name}]": fields(family.settings)
                     for name, family in FAMILIES.items() if family.settings is not None})
    return expected


def test_the_config_reference_lists_every_key_of_every_section():
    page = _extension("configref").render()
    listed = {table: set(keys) for table, keys in _tables(page).items()}
    assert listed == _expected_config_keys()
    # every schema the config package exports is a table of the page
    from workbench.experiment import config as c

    schemas = {getattr(c, n) for n in c.__all__
               if inspect.isclass(getattr(c, n)) and issubclass(getattr(c, n), BaseModel)}
    shown = {schema for _, schema, _ in _extension("configref").sections()}
    assert schemas <= shown, f"not in the config reference: {schemas - shown}"


def test_the_config_reference_shows_types_defaults_and_checks():
    page = _extension("configref").render()
    assert "| `trials` | int | `20` | >= 1, <= 1,000,000 |" in page
    assert "| `n_stages` | int or none | `(1)` | <= 10,000, checked by `BaseBoostRegressor` |" \
        in page
    assert '| `sampler` | "tpe" \\| "random" | `"tpe"` |  |' in page
    assert "| `onsite` | list of str | `required` |  |" in page
    # each key's meaning, from the schema's Parameters section (a [model] key from
    # BoostSettings', which ModelConfig's points to)
    assert "| `trials` | int | `20` | >= 1, <= 1,000,000 | Trials per study. |" in page
    assert "| `n_stages` | int or none | `(1)` | <= 10,000, checked by `BaseBoostRegressor` | " \
        "The boosting stages `K`. |" in page


def test_the_cli_reference_lists_every_command_and_option():
    import argparse

    from workbench.experiment.cli.parser import build_parser

    page = _extension("cliref").render()
    tables = _tables(page)
    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(tables) == {f"workbench {name}" for name in subparsers.choices}
    for name, sub in subparsers.choices.items():
        cells = " ".join(tables[f"workbench {name}"])
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
                continue  # (a hidden option: a renamed one, refused with its new name)
            for option in action.option_strings or [action.metavar or action.dest]:
                assert option in cells, f"workbench {name} {option} not in the CLI reference"


def test_the_api_reference_names_modules_and_names_that_exist():
    text = (DOCS / "reference" / "api.rst").read_text()
    modules = re.findall(r"^   (workbench[\w.]*)$", text, flags=re.M)
    assert "workbench" in modules and "workbench.datasets" in modules
    for name in modules:
        module = importlib.import_module(name)
        for public in getattr(module, "__all__", []):
            assert getattr(module, public, None) is not None, f"{name}.{public}"


#: numpydoc's checks that a docstring documents exactly its signature: it exists (GL08),
#: every parameter is in its Parameters section (PR01), nothing there is not a parameter
#: (PR02), and a callable that returns something says what in a Returns section (RT01). A
#: class documents its constructor's parameters (scikit-learn's layout; a dataclass's or a
#: config section's fields).
PARAMETER_CHECKS = {"GL08", "PR01", "PR02", "RT01"}

#: The rest of numpydoc's set that the core and the API keep: every documented parameter and
#: return value has a description (PR07, RT03), a parameter's type uses the short names
#: ("int", "bool", "str": PR06) and neither ends nor starts badly (PR05, PR08-PR10, RT04,
#: RT05), a single return value is given by its type alone (RT02), a generator says what it
#: yields (YD01), a See Also entry has a description (SA02-SA04), the summary and sections
#: are well formed (GL01, GL03, GL05-GL07, GL09, GL10, SS01-SS04). Left out, as noise for
#: this code base: ES01 (extended summary), EX01 (examples), SA01 (See Also everywhere), SS05
#: and SS06 (summaries in the third person or over two lines), GL02 (closing quotes), PR03
#: (the parameters' documented order: a config section's or estimator's grouped by meaning)
#: and PR04 (a type for every name of a group such as "topology, shape : As in simulate").
FORM_CHECKS = {"PR05", "PR06", "PR07", "PR08", "PR09", "PR10", "RT02", "RT03", "RT04", "RT05",
               "YD01", "SA02", "SA03", "SA04", "GL01", "GL03", "GL05", "GL06", "GL07", "GL09",
               "GL10", "SS01", "SS02", "SS03", "SS04"}


def _core_modules():
    """The core's public modules: ``workbench/*.py`` and ``workbench/datasets/*.py`` (not
    ``_private.py``)."""
    package = ROOT / "workbench"
    return [f"workbench.{p.stem}" for p in sorted(package.glob("*.py"))
            if not p.stem.startswith("_")] + \
        [f"workbench.datasets.{p.stem}" for p in sorted((package / "datasets").glob("*.py"))
         if not p.stem.startswith("_")]


def _public_names():
    """``{qualified name: object}`` of every function and class the API reference lists, of
    every public name of the core's modules (in their ``__all__`` or not: a name without a
    leading underscore is public, PEP 8), and of the experiment API's names
    (``workbench.experiment.api``)."""
    text = (DOCS / "reference" / "api.rst").read_text()
    out = {}
    for module_name in [*re.findall(r"^   (workbench[\w.]*)$", text, flags=re.M),
                        *_core_modules(), "workbench.experiment.api"]:
        module = importlib.import_module(module_name)
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            if inspect.isclass(obj) or inspect.isfunction(obj):
                out.setdefault(f"{obj.__module__}.{obj.__qualname__}", obj)
    for module_name in _core_modules():
        for name, obj in vars(importlib.import_module(module_name)).items():
            if not name.startswith("_") and (inspect.isclass(obj) or inspect.isfunction(obj)) \
                    and obj.__module__ == module_name:
                out.setdefault(f"{module_name}.{obj.__qualname__}", obj)
    return out


def _public_methods(names):
    """The qualified names of the public methods and properties of the classes among
    ``names``, each under the project's class that defines it (not scikit-learn's, pydantic's
    or the standard library's). An override of a method a project base class defines is
    validated there: its parameters and returns are the base's (autodoc shows the base's
    docstring where the override has none)."""
    out = set()
    for cls in (obj for obj in names.values() if inspect.isclass(obj)):
        ours = [k for k in cls.__mro__ if k.__module__.startswith("workbench")]
        for i, klass in enumerate(ours):
            for name, member in vars(klass).items():
                member = getattr(member, "__func__", member)  # a class or static method
                overrides = any(name in vars(base) for base in ours[i + 1:])
                if not name.startswith("_") and not overrides and (
                        inspect.isfunction(member) or isinstance(member, property)):
                    out.add(f"{klass.__module__}.{klass.__qualname__}.{name}")
    return out


def test_every_public_name_documents_its_parameters_and_returns():
    """numpydoc's own validation of every public function, class and method of the core and
    of the API reference (``make docs`` fails on their reST errors): the parameter checks and
    the form checks (:data:`PARAMETER_CHECKS`, :data:`FORM_CHECKS`)."""
    from numpydoc.validate import ERROR_MSGS, get_doc_object, validate

    CHECKS = PARAMETER_CHECKS | FORM_CHECKS
    assert CHECKS <= set(ERROR_MSGS)  # numpydoc's codes, none misspelt
    problems, names = [], _public_names()
    methods = _public_methods(names)
    assert "workbench.boosting.BaseBoostRegressor.fit" in methods  # the walk finds methods
    assert "workbench.parallel.run_plans" in names  # and the core's modules off the reference
    assert "workbench.bases.ridge" in names  # and their public names outside __all__
    for name, obj in sorted(names.items()):
        found = [f"{name}: {code} {message}" for code, message in
                 validate(get_doc_object(obj))["errors"] if code in CHECKS]
        problems += found
    for name in sorted(methods):
        problems += [f"{name}: {code} {message}" for code, message in
                     validate(name)["errors"] if code in CHECKS]
    assert not problems, f"{len(problems)} problems:\n" + "\n".join(problems)


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links, self.external = set(), [], []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        for key in ("href", "src"):
            url = attrs.get(key)
            if not url:
                continue
            if urlsplit(url).scheme in ("http", "https", "ftp") or url.startswith("//"):
                if tag in ("script", "img") or (tag == "link" and "stylesheet" in
                                                 (attrs.get("rel") or "")):
                    self.external.append(url)
            elif not url.startswith(("mailto:", "javascript:", "data:")):
                self.links.append(url)


def _check_links(html_dir):
    pages, broken, fetched = {}, [], set()
    for path in html_dir.rglob("*.html"):
        parser = _Links()
        parser.feed(path.read_text(errors="replace"))
        pages[path] = parser
        fetched.update(parser.external)
    for path, parser in pages.items():
        if "_modules" in path.parts or "_static" in path.parts:  # source pages, theme files
            continue
        for url in parser.links:
            parts = urlsplit(url)
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{path.relative_to(html_dir)}: {url}")
            elif parts.fragment and target.suffix == ".html" and target in pages \
                    and unquote(parts.fragment) not in pages[target].ids:
                broken.append(f"{path.relative_to(html_dir)}: {url} (no such anchor)")
    return broken, fetched


def test_the_site_builds_without_warnings_and_without_broken_links(tmp_path):
    """The whole site but the gallery's runs (``-D plot_gallery=0``), from a copy of docs/."""
    pytest.importorskip("sphinx")
    src = tmp_path / "docs"
    shutil.copytree(DOCS, src, ignore=shutil.ignore_patterns(
        "_build", "auto_examples", "generated", "config.md", "cli.md", "__pycache__"))
    shutil.copy(ROOT / "CHANGES.md", tmp_path / "CHANGES.md")
    out = tmp_path / "html"
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q",
         "-D", "plot_gallery=0", "-d", str(tmp_path / "doctrees"), str(src), str(out)],
        capture_output=True, text=True, env={**_env(), "MPLBACKEND": "Agg"})
    assert build.returncode == 0, build.stderr[-4000:]
    assert (out / "reference" / "config.html").is_file()
    assert (out / "reference" / "cli.html").is_file()
    assert (out / "auto_examples" / "index.html").is_file()
    broken, fetched = _check_links(out)
    assert not broken, "\n".join(broken[:20])
    assert all("mathjax" in url.lower() for url in fetched), fetched


def _env():
    import os

    env = dict(os.environ)
    # the checkout's package first, as in the tests (conf.py puts its own parent first too)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env
