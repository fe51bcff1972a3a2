"""The package's layout rules (issue #20): modules of one idea, short functions, no import cycles."""

import ast
from pathlib import Path

import breastcore

ROOT = Path(breastcore.__file__).parent
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 85


def _modules():
    return {".".join(p.relative_to(ROOT.parent).with_suffix("").parts).removesuffix(".__init__"): p
            for p in ROOT.rglob("*.py")}


def _imports(name, path, modules):
    """Package modules that ``name`` imports, at any depth of its code (function-level imports too)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)] + (node.module.split(".") if node.module else [])
            elif (node.module or "").startswith("breastcore"):
                base = node.module.split(".")
            else:
                continue
            for candidate in [".".join(base)] + [".".join(base + [a.name]) for a in node.names]:
                if candidate in modules and candidate != "breastcore":
                    found.add(candidate)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name in modules and a.name != "breastcore"}
    return found


def _cycles(graph):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_the_import_graph_has_no_cycle():
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    assert _cycles(graph) == []
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]   # the check finds one


def test_no_module_over_400_lines_and_no_function_over_85():
    long_modules = {str(p.relative_to(ROOT)): n for p in ROOT.rglob("*.py")
                    if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long_modules == {}
    long_functions = [(str(p.relative_to(ROOT)), node.name, node.end_lineno - node.lineno + 1)
                      for p in ROOT.rglob("*.py") for node in ast.walk(ast.parse(p.read_text()))
                      if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                      and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]
    assert long_functions == []


def test_tests_mirror_the_package_and_never_reach_into_benchmarks():
    tests = Path(__file__).parent
    folders = {p.name for p in tests.iterdir() if p.is_dir() and not p.name.startswith((".", "__"))}
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    assert folders and folders <= packages, f"test folders that name no breastcore subpackage: {folders - packages}"
    # a test of a subpackage's module lives in that subpackage's folder
    reaching = [str(p.relative_to(tests)) for p in tests.rglob("test_*.py")
                if p.parent != tests and "sys.path" in p.read_text()]
    assert reaching == []
