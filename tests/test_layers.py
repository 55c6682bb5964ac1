"""The package's layers import one way, compiled functions take named bundles, and offsets have names.

Layers, from the ground up: ``model`` (the compiled ground floor: the law ABI,
the generic rules, the loop) below ``problems`` and ``integrators``, below the
core's driver ``hybrid``, below ``engine`` (``simulate`` and ``run``), below
``certify`` (checking a reference log), below the apps (``bench``,
``bifurcation``, ``periodic``, ``simulation``, ``testing``), below ``cli``. The supervised
worker processes (``workers``) are a floor of their own that imports no app:
the apps' tasks are calls into their packages. Only the engine and the
integrators reach the core's driver: every app runs a problem through the
engine, under its defaults and its checks. No app imports ``cli``; a command of
``cli`` maps its arguments onto one request and calls one app function, and no
function there is a pipeline (longer than 60 lines). No import circle anywhere, type-only
imports included, and no module imports a private name of another package. The
test reads every module's imports (deferred ones inside functions included)
with ``ast``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1] / "src" / "nsbench"
COMPILERS = {"jit", "hot", "inline", "njit", "cfunc"}


def _modules() -> dict[str, ast.Module]:
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(("nsbench", *parts)).removesuffix(".__init__")
        out[name] = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return out


MODULES = _modules()


def _runtime_nodes(tree: ast.AST):
    """Every node except those under ``if TYPE_CHECKING:`` (annotations, never imported at run time)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            continue
        yield node
        yield from _runtime_nodes(node)


def _imports(tree: ast.Module) -> set[str]:
    found = set()
    for node in _runtime_nodes(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nsbench"):
            found.add(node.module)
            for alias in node.names:
                found.add(f"{node.module}.{alias.name}")
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("nsbench"))
    return {name for name in found if name in MODULES}


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "nsbench"


def _package_edges() -> dict[tuple[str, str], list[str]]:
    edges: dict[tuple[str, str], list[str]] = {}
    for name, tree in MODULES.items():
        for target in _imports(tree):
            a, b = _layer(name), _layer(target)
            if a != b:
                edges.setdefault((a, b), []).append(f"{name} -> {target}")
    return edges


@pytest.mark.parametrize(
    "lower, upper",
    [
        ("model", "problems"),
        ("model", "integrators"),
        ("model", "hybrid"),
        ("model", "engine"),
        ("model", "results"),
        ("model", "bench"),
        ("problems", "integrators"),
        ("problems", "hybrid"),
        ("problems", "engine"),
        ("integrators", "hybrid"),
        ("integrators", "engine"),
        ("hybrid", "engine"),
        ("hybrid", "bench"),
        ("engine", "bench"),
        ("engine", "cli"),
        ("engine", "certify"),
        ("certify", "bench"),
        ("certify", "bifurcation"),
        ("certify", "periodic"),
        ("certify", "testing"),
        ("certify", "simulation"),
        ("certify", "cli"),
        *(
            ("workers", app)
            for app in (
                "archive",
                "bench",
                "bifurcation",
                "periodic",
                "simulation",
                "testing",
                "certify",
                "cli",
                "engine",
            )
        ),
        # an app runs a request; the command line builds it: no app imports the command line
        *((app, "cli") for app in ("archive", "bench", "bifurcation", "periodic", "simulation", "testing")),
        # the archive is an app above the bench: nothing below it imports it
        *((lower, "archive") for lower in ("model", "problems", "integrators", "hybrid", "engine", "certify", "bench")),
        # the checked inputs and the factory probe, shared by the apps and the command line
        *(
            (leaf, upper)
            for leaf in ("inputs", "factory_probe")
            for upper in ("bench", "bifurcation", "simulation", "cli")
        ),
    ],
)
def test_a_lower_layer_never_imports_a_higher_one(lower, upper):
    offending = _package_edges().get((lower, upper), [])
    assert not offending, f"{lower} imports {upper}: {offending}"


#: The packages and modules that may import the core's driver (``nsbench.hybrid``) besides itself.
HYBRID_USERS = ("engine", "integrators")


def test_only_the_engine_and_the_integrators_import_the_core_driver():
    # sweeps, Lyapunov exponents, periodic orbits and continuation once called run_hybrid with
    # defaults of their own and no missed-crossing check; they run through nsbench.engine.run now
    edges = _package_edges().items()
    offending = sorted(edge for (a, b), found in edges if b == "hybrid" and a not in HYBRID_USERS for edge in found)
    assert not offending, offending


def test_the_simulate_command_imports_no_part_of_the_bench():
    # `nsbench simulate --integrator reference` certifies its log through nsbench.certify, below the bench:
    # the command run in a fresh interpreter loads no module of nsbench.bench
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from nsbench.cli import main\n"
        "code = main(['simulate', 'two-dof', '--case', '1', '--integrator', 'reference', '--t-end', '5'])\n"
        "print(code, sorted(m for m in sys.modules if m.startswith('nsbench.bench')))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "certified error of this log" in done.stdout, done.stdout  # the certification ran
    assert done.stdout.strip().splitlines()[-1] == "0 []", done.stdout
    assert not [t for t in _imports(MODULES["nsbench.certify"]) if t.startswith("nsbench.bench")]


def test_no_import_circle_among_problems_integrators_and_the_core():
    core = {"model", "problems", "integrators", "hybrid"}
    graph: dict[str, set[str]] = {name: set() for name in core}
    for a, b in _package_edges():
        if a in core and b in core:
            graph[a].add(b)

    def reaches(start: str, goal: str, seen: frozenset = frozenset()) -> bool:
        return any(nxt == goal or (nxt not in seen and reaches(nxt, goal, seen | {nxt})) for nxt in graph[start])

    circles = [name for name in core if reaches(name, name)]
    assert not circles, f"import circle through {circles}: {graph}"


def test_the_core_imports_no_integrator_and_no_problem_module():
    # the loop and the rules call a problem's law and an integrator's kernel through function tables
    for name in ("nsbench.model.loop", "nsbench.model.rules", "nsbench.model.law", "nsbench.hybrid.run"):
        bad = [
            t
            for t in _imports(MODULES[name])
            if t.startswith(("nsbench.integrators.", "nsbench.problems."))
            and not t.startswith(("nsbench.integrators.base", "nsbench.problems.base"))
        ]
        assert not bad, f"{name} imports {bad}"


def _compiled_functions():
    for name, tree in MODULES.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                for deco in node.decorator_list:
                    target = deco.func if isinstance(deco, ast.Call) else deco
                    ident = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
                    if ident in COMPILERS:
                        yield name, node
                        break


def test_no_compiled_function_takes_more_than_12_arguments():
    wide = [
        f"{name}.{fn.name}: {len(fn.args.args)}"
        for name, fn in _compiled_functions()
        if len(fn.args.args) + len(fn.args.kwonlyargs) > 12
    ]
    assert not wide, f"group these arguments in named bundles: {wide}"
    assert sum(1 for _ in _compiled_functions()) > 50  # the scan sees the kernels


# A subscript of a parameter or option vector or of a counter vector whose index is a number (``p[3 + 6*nb]``,
# ``fo[2]``, ``counters[0]``).
_BARE = re.compile(r"\b(p|fo|prob\.p|counters|cnt)\[\s*[0-9][^\]]*\]")


# A slot of a record in heyoka's runtime parameters taken by a number (``par[off + 1]``): the slots have names.
_BARE_RECORD = re.compile(r"\b(par|pars|ta\.pars)\[[^\]]*[+-]\s*[0-9]")


def test_no_bare_offset_into_a_parameter_or_option_vector():
    offenders = []
    for path in ROOT.rglob("*.py"):
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if _BARE.search(code) or _BARE_RECORD.search(code):
                offenders.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not offenders, offenders


def test_one_status_vocabulary():
    # Status is defined once; the run outcomes of the compiled loop map onto it one to one
    from nsbench.hybrid.run import RUN_STATUS
    from nsbench.model import abi
    from nsbench.results import Status as from_results
    from nsbench.status import Status

    assert from_results is Status
    codes = [v for k, v in vars(abi).items() if k.startswith("RUN_")]
    assert sorted(RUN_STATUS) == sorted(codes) and set(RUN_STATUS.values()) <= set(Status)
    defined = [
        name
        for name, tree in MODULES.items()
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef) and node.name == "Status"
    ]
    assert defined == ["nsbench.status"]


def test_statuses_are_compared_with_the_members_never_with_their_text():
    # ``rows["status"] == "crashed"`` keeps working if the text changes only by luck: compare with Status.CRASHED
    from nsbench.status import Status

    texts = "|".join(re.escape(s.value) for s in Status)
    literal = re.compile(rf"status\w*\"?\]?\s*[=!]=\s*[\"']({texts})[\"']|[\"']({texts})[\"']\s*[=!]=\s*\S*status")
    offenders = []
    for path in ROOT.rglob("*.py"):
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if literal.search(line.split("#", 1)[0]):
                offenders.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not offenders, offenders


def _problem_family(node: ast.AST) -> bool:
    """``<problem>.family`` or ``getattr(<problem>, "family", ...)``: a problem's family label (an
    integrator's ``caps.family`` of methods is another vocabulary, read from ``caps``/``self``)."""
    if isinstance(node, ast.Attribute) and node.attr == "family":
        owner = ast.unparse(node.value)
        return "problem" in owner or owner in ("p", "prob")
    if isinstance(node, ast.Call) and ast.unparse(node.func) == "getattr" and len(node.args) >= 2:
        return isinstance(node.args[1], ast.Constant) and node.args[1].value == "family"
    return False


def test_no_problem_is_told_apart_by_its_family_or_its_name():
    """Outside ``problems/``, what a problem is comes from its declared ``traits``
    (:class:`nsbench.problems.base.Traits`): no comparison with its ``family`` label, and no
    comparison of anything with the name of a built-in problem."""
    from nsbench.problems import list_problems

    names = set(list_problems())
    # pi_groups(name) is the paper's Table 3 for its two named problems: a public function of the name
    allowed = {"nsbench.units"}
    found = []
    for module, tree in MODULES.items():
        if module.startswith("nsbench.problems") or module in allowed:
            continue
        for node in ast.walk(tree):
            if not isinstance(node, ast.Compare):
                continue
            sides = [node.left, *node.comparators]
            literals = {
                c.value
                for side in sides
                for c in ast.walk(side)
                if isinstance(c, ast.Constant) and isinstance(c.value, str)
            }
            if any(_problem_family(side) for side in sides) or literals & names:
                found.append(f"{module}:{node.lineno}: {ast.unparse(node)}")
    assert not found, "\n".join(found)


def _all_imports(tree: ast.Module) -> set[str]:
    """Every module ``tree`` imports, type-only imports included; ``from P import sub`` names ``P.sub``
    alone where ``sub`` is a module (a parent package's ``__init__`` runs first for every import of a
    submodule, which is no circle)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nsbench"):
            subs = [f"{node.module}.{a.name}" for a in node.names if f"{node.module}.{a.name}" in MODULES]
            found.update(subs)
            if len(subs) < len(node.names):
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("nsbench"))
    return {name for name in found if name in MODULES}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def test_the_circle_finder_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle_anywhere_type_only_imports_included():
    graph = {name: _all_imports(tree) - {name} for name, tree in MODULES.items()}
    circles = _circles(graph)
    detail = [[f"{m} -> {sorted(graph[m] & set(c))}" for m in c] for c in circles]
    assert not circles, detail
    packages: dict[str, set[str]] = {}
    for name, targets in graph.items():
        packages.setdefault(_layer(name), set()).update(_layer(t) for t in targets if _layer(t) != _layer(name))
    assert not _circles(packages), _circles(packages)


def test_no_module_imports_a_private_name_of_another_package():
    # within a package its modules share private helpers; across packages only the public names
    def package(module: str) -> str:
        return ".".join(module.split(".")[:2])

    found = []
    for name, tree in MODULES.items():
        for node in ast.walk(tree):
            if not (isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("nsbench")):
                continue
            if package(node.module) == package(name):
                continue
            private_module = any(part.startswith("_") for part in node.module.split(".")[1:])
            for alias in node.names:
                private = alias.name.startswith("_") and not alias.name.startswith("__")
                if private_module or private:
                    found.append(f"{name}: from {node.module} import {alias.name}")
    assert not found, found


#: The packages whose functions are the apps' entry points.
APPS = ("archive", "bench", "bifurcation", "periodic", "simulation", "testing")
#: Commands whose whole pipeline lives in an app: the module declares its arguments (``add_parser``),
#: maps them onto one request (``request``) and calls one app function on it (``main``).
REQUEST_COMMANDS = ("bench", "bifurcation", "continuation", "lyapunov", "run", "simulate")
#: Functions of ``cli/`` longer than :data:`CLI_FUNCTION_LINES` whose pipeline has not moved to
#: its app yet: issue 50 item 6 moved them all (the sweep's, the continuation's, the bench's and the
#: run's, Lyapunov's, the simulation's and the history's), and the set stays empty.
LONG_CLI_FUNCTIONS: set[str] = set()
CLI_FUNCTION_LINES = 60


def _cli_functions():
    for path in sorted((ROOT / "cli").glob("*.py")):
        tree = MODULES[f"nsbench.cli.{path.stem}".removesuffix(".__init__")]
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path.stem, node


def test_no_function_of_the_command_line_is_a_pipeline():
    # a command maps arguments and calls its app: 60 lines hold that (add_parser only declares arguments)
    long = {
        f"{module}.{fn.name}": fn.end_lineno - fn.lineno + 1
        for module, fn in _cli_functions()
        if fn.name != "add_parser" and fn.end_lineno - fn.lineno + 1 > CLI_FUNCTION_LINES
    }
    grown = {name: n for name, n in long.items() if name not in LONG_CLI_FUNCTIONS}
    assert not grown, f"move these pipelines into their app (a request and one app function): {grown}"
    shrunk = LONG_CLI_FUNCTIONS - set(long)
    assert not shrunk, f"no longer over {CLI_FUNCTION_LINES} lines: take them off LONG_CLI_FUNCTIONS: {shrunk}"


def _app_names(tree: ast.Module) -> set[str]:
    """The names a module imports from the apps' packages."""
    return {
        alias.asname or alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module and _layer(node.module) in APPS
        for alias in node.names
    }


def _called(fn: ast.FunctionDef, names: set[str]) -> list[str]:
    return [ast.unparse(c.func) for c in ast.walk(fn) if isinstance(c, ast.Call) and ast.unparse(c.func) in names]


@pytest.mark.parametrize("command", REQUEST_COMMANDS)
def test_a_command_builds_one_request_and_calls_one_app_function(command):
    tree = MODULES[f"nsbench.cli.{command}"]
    functions = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert set(functions) == {"add_parser", "main", "request"}, sorted(functions)
    apps = _app_names(tree)
    built = _called(functions["request"], apps)
    assert len(built) == 1 and built[0].endswith("Request"), built  # the request: every value checked there
    ran = _called(functions["main"], apps | {"request"})
    assert len(ran) == 2 and "request" in ran, ran  # request(args), then one app function
    assert not _called(functions["add_parser"], apps)
