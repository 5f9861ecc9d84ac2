"""The layers hold: the core never imports the experiment layer, MLflow, Optuna or matplotlib;
the experiment layer's homes import one way, as their docstrings say; MLflow only in
``tracking/``, Optuna's storages and private names only in ``storage/``; the layout page is
what ``tools/layout.py`` writes."""

import ast
import functools
import importlib.util
import subprocess
import sys
from pathlib import Path

import workbench

PACKAGE = Path(workbench.__file__).parent
EXPERIMENT = PACKAGE / "experiment"
FORBIDDEN = ("mlflow", "optuna", "matplotlib", "shap")


def _core_files():
    files = [p for p in PACKAGE.rglob("*.py") if EXPERIMENT not in p.parents]
    assert len(files) >= 8, files  # the test must look at the real core
    return files


def test_importing_the_core_loads_no_experiment_dependencies():
    modules = sorted(
        f"workbench.{p.relative_to(PACKAGE).with_suffix('').as_posix().replace('/', '.')}"
        .removesuffix(".__init__") for p in _core_files())
    code = ("import sys\n" + "".join(f"import {m}\n" for m in modules) +
            f"bad = [m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r} "
            "or m.startswith('workbench.experiment')]\nprint(bad)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_core_sources_do_not_import_the_experiment_layer():
    for path in _core_files():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            else:
                continue
            for name in names:
                assert "experiment" not in name, f"{path} imports {name}"
                assert name.split(".")[0] not in FORBIDDEN, f"{path} imports {name}"


_LOADED = """
import sys
from workbench.experiment.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
heavy = {"mlflow", "optuna", "shap", "sklearn", "lightgbm"}
print("LOADED:" + ",".join(sorted({m.split(".")[0] for m in sys.modules} & heavy)))
"""


def _loaded(*argv: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", _LOADED, *argv], capture_output=True,
                         text=True, check=True)
    line = [x for x in out.stdout.splitlines() if x.startswith("LOADED:")][-1]
    return {m for m in line.removeprefix("LOADED:").split(",") if m}


def test_the_command_imports_heavy_libraries_only_where_needed(tmp_path):
    """``workbench --help`` loads none of the heavy libraries; ``workbench simulate`` none of
    the experiment layer's (MLflow, Optuna, SHAP)."""
    assert _loaded("--help") == set()
    assert _loaded("sweep", "--help") == set()
    assert _loaded("predict", "--help") == set()
    simulated = _loaded("simulate", "--experiments", "10", "--out", str(tmp_path / "s.csv"))
    assert not simulated & {"mlflow", "optuna", "shap"}, simulated
    assert (tmp_path / "s.csv").is_file()  # the command did run
    # the guard can fail: a command that fits loads the estimators
    config = tmp_path / "c.toml"
    config.write_text('[data]\ndata_dir = "/nonexistent"\n[model]\nbasis = "ridge"\n')
    assert "sklearn" in _loaded("evaluate", str(config), "--no-track")


def test_import_workbench_is_light():
    out = subprocess.run([sys.executable, "-c", "import sys, workbench; print(sorted("
                          "{m.split('.')[0] for m in sys.modules} & {'sklearn', 'lightgbm', "
                          "'pandas', 'mlflow'}))"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert workbench.BaseBoostCV.__name__ == "BaseBoostCV"  # names still load on first use


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("").as_posix().replace("/", ".")
    return rel.removesuffix(".__init__")


def _runtime_imports(path: Path, modules: set[str], type_only: bool = False) -> set[str]:
    """The workbench modules ``path`` imports when it runs (at module level or inside
    functions; imports under ``if TYPE_CHECKING:`` never run and are left out unless
    ``type_only``)."""
    tree = ast.parse(path.read_text())
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    skipped = set()
    for node in ast.walk(tree):
        if not type_only and isinstance(node, ast.If) \
                and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(n) for n in ast.walk(node))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            base = (f"{base}.{node.module}" if node.module else base) if node.level \
                else node.module or ""
            # "from pkg import module" imports pkg.module; "from pkg import name" only pkg
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in modules:  # "import a.b.c" of a non-module name
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph(type_only: bool = False) -> dict[str, set[str]]:
    """Module -> the workbench modules it imports (``type_only``: those imported for type
    checking only too). The sources are parsed once per test process (about 1 CPU-s a
    graph; the tests ask for one seven times); each call gets its own copy."""
    return {m: set(targets) for m, targets in _import_graph(type_only).items()}


@functools.cache
def _import_graph(type_only: bool) -> dict[str, frozenset[str]]:
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    modules = set(files)
    return {m: frozenset(_runtime_imports(p, modules, type_only)) for m, p in files.items()}


def room_graphs(graph: dict[str, set[str]]) -> dict[str, dict[str, set[str]]]:
    """For each package, the imports between its rooms: its modules and subpackages, each
    subpackage standing for every module inside it (the package's own ``__init__`` left
    out: it is the front over its rooms)."""
    packages = {m for m in graph if any(other.startswith(m + ".") for other in graph)}

    def room(package: str, module: str) -> str | None:
        if not module.startswith(package + "."):
            return None
        return f"{package}.{module[len(package) + 1:].split('.')[0]}"

    rooms: dict[str, dict[str, set[str]]] = {}
    for package in packages:
        edges: dict[str, set[str]] = {}
        for module, targets in graph.items():
            source = room(package, module)
            if source is None:
                continue
            edges.setdefault(source, set())
            for target in targets:
                inside = room(package, target)
                if inside is not None and inside != source:
                    edges[source].add(inside)
        rooms[package] = edges
    return rooms


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle_in_the_package():
    """No two workbench modules import each other, directly or through others (imports inside
    functions count: a circle is a design smell even when the import is deferred). A
    package's __init__ importing its submodules counts too."""
    graph = import_graph()
    assert len(graph) >= 40 and "workbench.experiment.cli" in graph  # it sees the package
    assert _cycles(graph) == []
    # the check finds a circle when there is one
    assert _cycles({**graph, "workbench.losses": graph["workbench.losses"]
                    | {"workbench.boosting"}}) != []


def test_no_circle_with_type_only_imports():
    """Imports for type checking only (``if TYPE_CHECKING:``) run no code, but an arrow that
    runs back up is a design smell all the same: with them, still no circle."""
    graph = import_graph(type_only=True)
    assert _cycles(graph) == []
    # the check sees them: a family's type-only import of the config is an arrow
    assert "workbench.experiment.config" in graph["workbench.experiment.families.base"]
    assert "workbench.experiment.config" not in import_graph()[
        "workbench.experiment.families.base"]


def test_no_back_arrow_between_rooms():
    """In every package, its rooms (modules and subpackages, a subpackage standing for all
    its modules) import each other in one direction only, type-only imports included: e.g.
    the config package sits below the model families, and the loader above both."""
    rooms = room_graphs(import_graph(type_only=True))
    assert "workbench.experiment.config" in rooms["workbench.experiment"]
    assert {package: _cycles(edges) for package, edges in rooms.items()
            if _cycles(edges)} == {}
    # the check finds a back arrow when there is one: a config module importing a family
    graph = import_graph(type_only=True)
    back = {**graph, "workbench.experiment.config.data": graph[
        "workbench.experiment.config.data"] | {"workbench.experiment.families.base"}}
    assert _cycles(room_graphs(back)["workbench.experiment"]) != []


#: The one package allowed to use what Optuna keeps private.
OPTUNA_ADAPTER = PACKAGE / "experiment" / "storage"


def _optuna_private_names() -> set[str]:
    """Private attribute and method names Optuna's classes define (``self._x = ...``,
    ``def _x``), read from its installed sources."""
    import optuna

    names = set()
    for path in Path(optuna.__file__).parent.rglob("*.py"):
        text = path.read_text(encoding="utf-8", errors="replace")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id == "self" and node.attr.startswith("_") \
                    and not node.attr.startswith("__"):
                names.add(node.attr)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and node.name.startswith("_") and not node.name.startswith("__"):
                names.add(node.name)
    return names


def optuna_private_uses(source: str, private: set[str]) -> list[str]:
    """Where ``source`` imports an Optuna module or name marked private (a ``_`` component:
    ``optuna.storages.journal._file``, ``optuna_dashboard._cli``) or reads a private Optuna
    attribute of an object other than ``self``/``cls`` (``study._storage``)."""
    found = []
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module \
                and node.module.split(".")[0] in ("optuna", "optuna_dashboard"):
            parts = node.module.split(".") + [a.name for a in node.names]
            found += [f"line {node.lineno}: from {node.module} import ..."
                      for p in parts if p.startswith("_") and not p.startswith("__")][:1]
        elif isinstance(node, ast.Import):
            found += [f"line {node.lineno}: import {a.name}" for a in node.names
                      if a.name.split(".")[0] in ("optuna", "optuna_dashboard")
                      and any(p.startswith("_") for p in a.name.split("."))]
        elif isinstance(node, ast.Attribute) and node.attr in private \
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
            found.append(f"line {node.lineno}: .{node.attr}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and ("optuna_dashboard._" in node.value or "optuna.storages._" in node.value):
            found.append(f"line {node.lineno}: {node.value[:40]!r}")
    return found


def test_only_the_storage_adapter_touches_optuna_s_private_names():
    """Optuna's internals (a study's ``_storage``, ``_study_id``, a trial's ``_trial_id``, the
    journal's private modules) are used in one package, whose upper bound on Optuna
    (pyproject) guards them; everything else uses Optuna's public API."""
    private = _optuna_private_names()
    assert {"_storage", "_study_id", "_trial_id"} <= private  # it reads Optuna's sources
    uses = {str(path.relative_to(PACKAGE)): optuna_private_uses(path.read_text(), private)
            for path in PACKAGE.rglob("*.py") if OPTUNA_ADAPTER not in path.parents}
    assert {k: v for k, v in uses.items() if v} == {}
    adapter = "\n".join(p.read_text() for p in sorted(OPTUNA_ADAPTER.glob("*.py")))
    assert optuna_private_uses(adapter, private)  # the adapter does
    # the check finds a use when there is one
    assert optuna_private_uses("def f(study):\n    return study._storage\n", private)
    assert optuna_private_uses("from optuna.storages.journal._file import get_lock_file\n",
                               private)


def _layout():
    """tools/layout.py, the layout page's generator, as a module."""
    path = PACKAGE.parent / "tools" / "layout.py"
    spec = importlib.util.spec_from_file_location("layout_tool", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_no_loose_module_at_the_top_of_the_experiment_layer():
    """Every module lives in a home (a package) but the layer's ``__init__`` and ``api``."""
    loose = sorted(p.name for p in EXPERIMENT.glob("*.py"))
    assert loose == ["__init__.py", "api.py"]
    assert len(_layout().homes()) >= 10  # it sees the homes


def _home(module: str) -> str | None:
    parts = module.split(".")
    if parts[:2] != ["workbench", "experiment"] or len(parts) < 3:
        return None
    return parts[2] if (EXPERIMENT / parts[2] / "__init__.py").is_file() else None


def home_arrows(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Home -> the other homes its modules import."""
    arrows: dict[str, set[str]] = {}
    for module, targets in graph.items():
        home = _home(module)
        if home is not None:
            arrows.setdefault(home, set()).update(
                t for t in map(_home, targets) if t is not None and t != home)
    return arrows


def test_each_home_imports_only_what_its_docstring_allows():
    """Each home's ``__init__`` says which homes it may import (``May import:``); its modules
    import no other (type-only imports and imports inside functions included), and the
    allowed homes form no circle, so no home imports one above it."""
    layout = _layout()
    homes = layout.homes()
    for home in homes:
        assert layout.allowed_paragraph(EXPERIMENT / home / "__init__.py"), \
            f"{home}/__init__.py has no 'May import:' paragraph"
    order = layout.layers()  # raises on a circle
    assert order[0] in ("process", "scoring") and order[-1] == "cli"
    arrows = home_arrows(import_graph(type_only=True))
    assert {h: sorted(a - layout.allowed(h)) for h, a in arrows.items()
            if a - layout.allowed(h)} == {}
    assert arrows["cli"] and arrows["runs"]  # it sees the imports
    # the check finds an arrow up when there is one: the config importing a family
    graph = import_graph(type_only=True)
    up = {**graph, "workbench.experiment.config.data": graph[
        "workbench.experiment.config.data"] | {"workbench.experiment.families.base"}}
    assert "families" in home_arrows(up)["config"] - layout.allowed("config")
    # and the generator reads the same arrows
    assert {h: layout.imported_homes(h) for h in homes} == {h: arrows.get(h, set())
                                                           for h in homes}


def test_the_layout_page_is_what_its_generator_writes():
    """docs/user_guide/layout.md is generated (``make layout``) so it cannot drift."""
    layout = _layout()
    page = layout.PAGE.read_text(encoding="utf-8")
    assert page == layout.render(), "docs/user_guide/layout.md is stale: run make layout"
    for home in layout.homes():
        assert f"### `{home}/`" in page
    assert "`run_outputs.py`" in page and "`_journal.py`" in page  # modules listed


def _imports_of(path: Path, runtime_only: bool = False) -> list[tuple[int, str]]:
    """(line, dotted name) of each import in ``path`` (``runtime_only``: not those under
    ``if TYPE_CHECKING:``) and of each attribute chain ``a.b.c`` read."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skipped = set()
    if runtime_only:
        for node in ast.walk(tree):
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                skipped.update(id(n) for n in ast.walk(node))
    found = []
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found += [(node.lineno, f"{node.module}.{a.name}") for a in node.names]
        elif isinstance(node, ast.Attribute):
            found.append((node.lineno, ast.unparse(node)))
    return found


def _outside(home: str) -> list[Path]:
    return [p for p in PACKAGE.rglob("*.py") if EXPERIMENT / home not in p.parents]


def test_mlflow_is_imported_only_under_tracking():
    """One home talks to MLflow; the others go through it (type-only imports count)."""
    found = {f"{p.relative_to(PACKAGE)}:{line}": name for p in _outside("tracking")
             for line, name in _imports_of(p) if name.split(".")[0] == "mlflow"}
    assert found == {}
    inside = [name for p in (EXPERIMENT / "tracking").rglob("*.py")
              for _, name in _imports_of(p) if name.split(".")[0] == "mlflow"]
    assert inside  # the check sees MLflow's imports


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):  # a parent that is not a package ("mlflow.source.name")
        return False


def mlflow_modules_named(source: str) -> list[str]:
    """The MLflow modules ``source`` names as text to import (``importlib.import_module``, a
    list of modules to load): string constants that are the name of one of MLflow's
    submodules, but a logger's (``logging.getLogger("mlflow.store.db.utils")``); a tag
    (``"mlflow.source.name"``) names none, nor a key ``"mlflow"``."""
    tree = ast.parse(source)
    loggers = {id(node.args[0]) for node in ast.walk(tree) if isinstance(node, ast.Call)
               and ast.unparse(node.func).endswith("getLogger") and node.args}
    return [f"line {node.lineno}: {node.value!r}" for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str)
            and node.value.startswith("mlflow.") and id(node) not in loggers
            and _is_module(node.value)]


def test_mlflow_modules_are_named_only_under_tracking():
    """Not even by name: the modules ``evaluate`` loads in the background while the model
    fits are listed by ``tracking/`` (``RECORD_MODULES``), not by the command line."""
    found = {str(p.relative_to(PACKAGE)): uses for p in _outside("tracking")
             if (uses := mlflow_modules_named(p.read_text(encoding="utf-8")))}
    assert found == {}
    from workbench.experiment.tracking import RECORD_MODULES

    assert "mlflow.pyfunc" in RECORD_MODULES
    # the check finds a name when there is one, and leaves loggers and tags alone
    assert mlflow_modules_named('MODULES = ("shap", "mlflow.pyfunc")\n')
    assert not mlflow_modules_named('import logging\nlogging.getLogger("mlflow.store")\n'
                                    'TAG = "mlflow.source.name"\n')


def test_optuna_storages_are_used_only_under_storage():
    """Opening, checking and failing stale trials of Optuna's storages is ``storage/``'s; a
    name of ``optuna.storages`` elsewhere appears only in annotations (``if TYPE_CHECKING:``)."""
    def uses(path: Path) -> list[str]:
        return [f"{path.relative_to(PACKAGE)}:{line}: {name}"
                for line, name in _imports_of(path, runtime_only=True)
                if name.startswith("optuna.storages")]

    assert [u for p in _outside("storage") for u in uses(p)] == []
    assert [u for p in (EXPERIMENT / "storage").rglob("*.py") for u in uses(p)]


def test_no_module_re_exports_another_s_names():
    """A module's ``__all__`` names what it defines, not what it imports from the project
    (no re-export kept for an old import path); only the packages' ``__init__`` and the
    promised ``workbench.experiment.api`` gather names from elsewhere."""
    problems = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "__init__.py" or path == PACKAGE / "experiment" / "api.py":
            continue
        tree = ast.parse(path.read_text())
        defined, imported, names = set(), set(), []
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                defined.add(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for target in targets:
                    if isinstance(target, ast.Name):
                        defined.add(target.id)
                        if target.id == "__all__":
                            names = [e.value for e in node.value.elts]
            elif isinstance(node, ast.ImportFrom) and (
                    node.level > 0 or (node.module or "").startswith("workbench")):
                imported.update(a.asname or a.name for a in node.names)
        problems += [f"{path.relative_to(PACKAGE.parent)}: {name}" for name in names
                     if name in imported and name not in defined]
    assert not problems, "re-exported names:\n" + "\n".join(problems)


def _project_classes() -> dict[str, type]:
    """Every class the package defines, by qualified name (``__main__`` modules left out)."""
    import inspect
    import pkgutil

    found = {}
    for info in pkgutil.walk_packages(workbench.__path__, "workbench."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for cls in vars(module).values():
            if inspect.isclass(cls) and cls.__module__ == info.name:
                found[f"{cls.__module__}.{cls.__qualname__}"] = cls
    return found


def split_classes(classes: dict[str, type]) -> list[str]:
    """Classes assembled from parts in other modules: a class with two or more of the
    project's classes as direct bases, or a project class (not an exception) that exactly one
    class inherits, from another module (a half of one class kept elsewhere)."""
    ours = {cls for cls in classes.values()}
    found = [f"{name}: bases {[b.__name__ for b in cls.__bases__ if b in ours]}"
             for name, cls in classes.items() if sum(b in ours for b in cls.__bases__) >= 2]
    for name, base in classes.items():
        if issubclass(base, BaseException):
            continue
        heirs = [cls for cls in classes.values() if base in cls.__bases__]
        if len(heirs) == 1 and heirs[0].__module__ != base.__module__:
            found.append(f"{name}: only {heirs[0].__module__}.{heirs[0].__qualname__} "
                         "inherits it")
    return found


def test_no_class_is_split_over_mixins():
    """A class is written in one place: not assembled from mixins kept in other modules (as
    ``Tracker`` was from ``ModelRecords`` and ``ArtifactRecords``, and ``ModelFamily`` from
    ``ResultMethods``, to keep files short). Interfaces several classes share (a model
    family, a config section) and exceptions are not halves."""
    classes = _project_classes()
    assert "workbench.experiment.tracking.runs.Tracker" in classes  # it sees the package
    assert split_classes(classes) == []
    # the check finds a split when there is one
    half = type("ModelRecords", (), {"__module__": "workbench.experiment.tracking.models"})
    other = type("ArtifactRecords", (), {"__module__": "workbench.experiment.tracking.a"})
    whole = type("Tracker", (half, other), {"__module__": "workbench.experiment.tracking.runs"})
    assert len(split_classes({"m": half, "a": other, "t": whole})) == 3
