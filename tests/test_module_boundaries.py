"""The core never imports the viewer (STYLE: tracer/ knows nothing of viewer/).

Two checks, since either alone misses a case: importing every tracer module in a fresh
interpreter sees imports at module level, and reading every tracer source sees imports
inside functions (run only when, say, a command is built).
"""
import ast
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TRACER = REPO / "tracer"

IMPORT_ALL_TRACER_MODULES = """
import importlib, json, pkgutil, sys
import tracer
names = [m.name for m in pkgutil.walk_packages(tracer.__path__, "tracer.")]
for name in names:
    importlib.import_module(name)
print(json.dumps({"tracer": tracer.__file__, "imported": names,
                  "viewer": sorted(n for n in sys.modules if n == "viewer" or n.startswith("viewer."))}))
"""


def test_importing_every_tracer_module_imports_no_viewer_module():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-c", IMPORT_ALL_TRACER_MODULES], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    result = json.loads(proc.stdout.splitlines()[-1])
    assert Path(result["tracer"]).resolve().is_relative_to(TRACER)  # this checkout's tracer, not another
    assert "tracer.cli" in result["imported"] and "tracer.formats.obj" in result["imported"]
    assert result["viewer"] == [], f"importing tracer/ loaded {result['viewer']}"


def imported_names(tree) -> list:
    """(line, module) of every import statement in a parsed module, at any depth."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            out.append((node.lineno, node.module))
    return out


def test_no_tracer_source_imports_the_viewer():
    sources = sorted(TRACER.rglob("*.py"))
    assert len(sources) > 20
    found = [f"{path.relative_to(REPO)}:{line} imports {name}"
             for path in sources for line, name in imported_names(ast.parse(path.read_text(), str(path)))
             if name == "viewer" or name.startswith("viewer.")]
    assert not found, "; ".join(found)


BLAS_CALLS = {"dot", "matmul", "inner", "tensordot", "vdot"}


def test_no_blas_products_outside_fixed_order():
    """numpy's @ and dot go to OpenBLAS, whose kernels (chosen by the CPU) add in their own order:
    geometry would differ in its last bits between machines. tracer/fixed_order.py adds term by term."""
    found = []
    for path in sorted(TRACER.rglob("*.py")):
        if path.name == "fixed_order.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
                found.append(f"{path.relative_to(REPO)}:{node.lineno} @")
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and \
                    node.func.attr in BLAS_CALLS and isinstance(node.func.value, ast.Name) and node.func.value.id == "np":
                found.append(f"{path.relative_to(REPO)}:{node.lineno} np.{node.func.attr}")
            if isinstance(node, ast.Call) and ast.unparse(node.func) == "np.linalg.norm" and \
                    not any(k.arg == "axis" for k in node.keywords):  # a vector's norm is a BLAS dot
                found.append(f"{path.relative_to(REPO)}:{node.lineno} np.linalg.norm of a vector")
    assert not found, "use tracer.fixed_order instead of: " + ", ".join(found)
