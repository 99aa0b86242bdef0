"""The layering rules: engine and app never load torch or training; engine never loads Qt; the
folders of training/ import only the pipeline stages before them."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _loaded_after(code: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys\nprint('\\n'.join(sorted(sys.modules)))"],
        capture_output=True, text=True, cwd=ROOT, check=True,
    ).stdout.split()
    return {m.split(".")[0] for m in out}


@pytest.mark.parametrize("code", [
    "import engine, engine.camera, engine.mesh, engine.icosphere, engine.contract, engine.strokes",
    "import app, app.main",
])
def test_fresh_interpreter_does_not_load_torch_or_training(code):
    loaded = _loaded_after(code)
    assert "torch" not in loaded
    assert "training" not in loaded


def test_cli_parser_does_not_load_torch():
    """`sketchmesh --help` and `sketchmesh infer` must not pay for torch (training registers lazily)."""
    assert "torch" not in _loaded_after("import sketchmesh.cli; sketchmesh.cli.build_parser()")


@pytest.mark.gui
def test_app_run_with_the_bundled_models_does_not_load_torch(tmp_path):
    """The whole app path of the README's launch command, in a fresh interpreter: window, bundled
    models, inference and a screenshot, with torch installed (the test extras) but never imported."""
    if not os.environ.get("DISPLAY"):
        pytest.skip("needs a display (tests/conftest.py starts Xvfb when it is installed)")
    sample = ROOT / "assets" / "samples" / "chair_chair_00018_v3.png"
    shot = tmp_path / "shot.png"
    code = (
        "import sys\n"
        "from sketchmesh.cli import main\n"
        f"rc = main(['--open', {str(sample)!r}, '--screenshot', {str(shot)!r}])\n"
        "print(rc, 'torch' in sys.modules)\n"
    )
    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "cfg"), XDG_DATA_HOME=str(tmp_path / "data"))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env, timeout=180)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split()[-2:] == ["0", "False"], done.stdout
    assert shot.stat().st_size > 0


def test_engine_does_not_load_qt():
    loaded = _loaded_after("import engine, engine.camera, engine.mesh, engine.icosphere")
    assert not {"PySide6", "shiboken6", "vtk", "vtkmodules"} & loaded


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package, forbidden", [
    ("engine", {"torch", "training", "app", "PySide6", "shiboken6", "vtk", "vtkmodules"}),
    ("app", {"torch", "training"}),
    ("training", {"app", "PySide6", "vtk", "vtkmodules"}),
])
def test_no_source_file_imports_across_layers(package, forbidden):
    """Static check, including imports inside functions, for every file of the layer."""
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no source files found under {package}/"
    for path in files:
        bad = _imports(path) & forbidden
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


# The folders of `training/`, in pipeline order: each may import only those before it (and the
# top-level helper `training._torch`), so the model never depends on how it is trained, evaluated
# or driven from the command line.
TRAINING_PIPELINE = ("render", "data", "model", "loop", "export", "evaluation", "bench", "cli")


def _training_imports(path: Path) -> set[str]:
    """The `training` sub-packages/modules a file imports, e.g. {"render", "_torch"}."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        modules = []
        if isinstance(node, ast.Import):
            modules = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules = [node.module]
        names |= {m.split(".")[1] for m in modules if m.startswith("training.")}
    return names


def test_training_folders_follow_the_pipeline():
    found = {p.name for p in (ROOT / "training").iterdir() if (p / "__init__.py").is_file()}
    assert found == set(TRAINING_PIPELINE), f"training/ packages {sorted(found)} != {sorted(TRAINING_PIPELINE)}"
    for i, folder in enumerate(TRAINING_PIPELINE):
        allowed = {folder, "_torch", *TRAINING_PIPELINE[:i]}
        for path in sorted((ROOT / "training" / folder).rglob("*.py")):
            bad = _training_imports(path) - allowed
            assert not bad, f"{path.relative_to(ROOT)} imports training.{sorted(bad)}; {folder}/ may use only {sorted(allowed)}"


def test_cli_works_without_the_training_package(tmp_path):
    """The frozen app ships without `training`: the dispatcher must still build and run `infer --help`."""
    code = (
        "import sys, importlib.abc\n"
        "class Block(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'training' or name.startswith('training.'):\n"
        "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "from sketchmesh.cli import build_parser, main\n"
        "p = build_parser()\n"
        "names = set(p._subparsers._group_actions[0].choices)\n"
        "assert 'infer' in names and 'train' not in names and 'data' not in names, names\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
