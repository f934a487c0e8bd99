"""Rules that keep the code walkable, checked on the source: no module imports a private module
of another package, no test, benchmark or notebook imports a private module, and no function
invents a PRNG key for its caller."""

import ast
import json
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "jaxtrack"
SHARED_PRIVATE = {"_custom_types", "_registries", "_tree", "_validation"}  # top-level helpers every package may use


def _package_of(path: pathlib.Path) -> tuple[str, ...]:
    return path.relative_to(ROOT).with_suffix("").parts[:-1]


def _imported_modules(path: pathlib.Path):
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(_package_of(path))[: len(_package_of(path)) - node.level + 1]
                parts = base + (node.module.split(".") if node.module else [])
            else:
                parts = (node.module or "").split(".")
            yield node.lineno, tuple(parts), [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, tuple(alias.name.split(".")), []


def test_no_package_imports_a_private_module_of_another():
    offences = []
    for path in PACKAGE.rglob("*.py"):
        own = _package_of(path)
        for line, parts, _ in _imported_modules(path):
            if not parts or parts[0] != "jaxtrack":
                continue
            for i, part in enumerate(parts[1:], start=1):
                private = part.startswith("_") and part not in SHARED_PRIVATE
                if private and tuple(parts[:i]) != own:
                    offences.append(f"{path.relative_to(ROOT)}:{line} imports {'.'.join(parts)}")
    assert not offences, "\n".join(offences)


def _outside_sources():
    for folder in ("tests", "benchmarks", "experiments"):
        for path in (ROOT / folder).rglob("*.py"):
            yield path, path.read_text()
    for path in (ROOT / "notebooks").glob("*.ipynb"):
        cells = json.loads(path.read_text())["cells"]
        yield path, "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")


def test_tests_benchmarks_and_notebooks_use_the_public_api():
    offences = []
    for path, text in _outside_sources():
        for node in ast.walk(ast.parse(text)):
            module = node.module if isinstance(node, ast.ImportFrom) else None
            names = [a.name for a in node.names] if isinstance(node, (ast.Import, ast.ImportFrom)) else []
            for dotted in ([module] if module else []) + (list(names) if isinstance(node, ast.Import) else []):
                parts = dotted.split(".")
                if parts[0] == "jaxtrack" and any(p.startswith("_") for p in parts[1:]):
                    offences.append(f"{path.relative_to(ROOT)}:{node.lineno} imports {dotted}")
    assert not offences, "\n".join(offences)


def test_no_function_defaults_a_prng_key():
    """A parameter named ``key`` (or ``*_key``) may default to None only where None means "no
    randomness" and the function never makes a key of its own."""
    offences = []
    for path in PACKAGE.rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            args = node.args
            positional = args.posonlyargs + args.args
            defaults = dict(zip([a.arg for a in positional[len(positional) - len(args.defaults):]], args.defaults))
            defaults.update({a.arg: d for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None})
            for name, default in defaults.items():
                if name != "key" and not name.endswith("_key"):
                    continue
                body = ast.unparse(node)
                is_none = isinstance(default, ast.Constant) and default.value is None
                if not is_none or "random.key(" in body or "PRNGKey(" in body:
                    offences.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}({name}={ast.unparse(default)})")
    assert not offences, "\n".join(offences)


def test_notebooks_are_stored_without_outputs():
    notebooks = sorted((ROOT / "notebooks").glob("*.ipynb"))
    assert len(notebooks) >= 3
    for path in notebooks:
        for cell in json.loads(path.read_text())["cells"]:
            if cell["cell_type"] == "code":
                assert not cell["outputs"] and cell["execution_count"] is None, f"{path.name}: outputs are not stripped"


def _module_name(path: pathlib.Path) -> tuple[str, ...]:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return parts[:-1] if parts[-1] == "__init__" else parts


def test_no_module_cycles_inside_a_package():
    """Within a package, no two modules import each other, directly or through others (imports
    inside functions count: a cycle hidden in a function is still a cycle)."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        edges = set()
        for _, parts, names in _imported_modules(path):
            for target in [parts + (n,) for n in names] + [parts]:
                if target in modules and target != name and target[:-1] == name[:-1] and target[-1] != "__init__":
                    edges.add(target)
                    break
        graph[name] = edges
    cycles = []

    def visit(node, stack, seen):
        for nxt in graph[node]:
            if nxt in stack:
                cycles.append(" -> ".join(".".join(m) for m in stack[stack.index(nxt):] + [nxt]))
            elif nxt not in seen:
                seen.add(nxt)
                visit(nxt, stack + [nxt], seen)

    for start in graph:
        if start[-1] != "__init__" and len(start) > 1 and start[-1].startswith("_"):
            visit(start, [start], {start})
    assert not cycles, "\n".join(sorted(set(cycles)))
