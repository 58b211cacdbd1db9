"""The layer rule of docs/architecture.md, read from the source (AST, no imports run).

Imports run one way: the base (errors, file writing, shipped files, the task
runner), then the core (science, configuration, data I/O), then training and
serving, then the measurement loop, the command line on top. A module may import
its own layer and the layers below it, never one above; nothing imports
``stiffnet.cli``; the predictor (``serving`` and everything it imports,
function-level imports included) never reaches torch, scikit-learn or mlflow,
nor the training code.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("stiffnet", "serving", "training")

#: Layers from the bottom; a module belongs to the longest prefix listed.
LAYERS: dict[str, tuple[str, ...]] = {
    "base": (
        "stiffnet",
        "stiffnet.errors",
        "stiffnet.io_utils",
        "stiffnet.plugins",
        "stiffnet.shipped",
    ),  # fmt: skip
    "core": (
        "stiffnet.config",
        # the task runner is infrastructure: the callers pass in their tasks and thread
        # limits; it reads only its own cluster's housekeeping from a shipped config
        "stiffnet.distributed",
        "stiffnet.effects",
        "stiffnet.simulator",
        "stiffnet.nlts",
        "stiffnet.geometry",
        "stiffnet.features",
        "stiffnet.recordings",
        "stiffnet.campaign",
        "stiffnet.dataset",
        "stiffnet.analyze",
        "stiffnet.plots",
        "stiffnet.restoring_force",
        "stiffnet.uncertainty",
        "stiffnet.discovery",
        "stiffnet.layers",
    ),  # fmt: skip
    "models": ("training", "serving"),
    "measurement": ("stiffnet.measurement",),
    # the Python front door (notebooks): re-exports the predictor; the base package cannot
    "api": ("stiffnet.api",),
    # the command line is one package (app, console, options, one module per command group)
    "cli": ("stiffnet.cli", "stiffnet.__main__"),
}
ORDER = list(LAYERS)
FORBIDDEN_IN_PREDICTOR = ("torch", "sklearn", "mlflow", "training")


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def all_modules(root: Path = ROOT) -> dict[str, Path]:
    return {
        module_name(p, root): p
        for pkg in PACKAGES
        for p in sorted((root / pkg).rglob("*.py"))
        if "__pycache__" not in p.parts
    }


def imports_of(name: str, source: str, is_package: bool, known: Iterable[str]) -> set[str]:
    """Every module ``source`` imports, at module level or inside functions.

    ``from a import b`` counts as ``a.b`` when that is a module, else as ``a``.
    """
    known = set(known)
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in known else target)
    return found


def layer_of(module: str) -> str | None:
    best, best_len = None, -1
    for layer, prefixes in LAYERS.items():
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best_len:
                best, best_len = layer, len(prefix)
    return best


def violations(graph: dict[str, set[str]]) -> list[str]:
    """Imports against the layer rule, and imports of ``stiffnet.cli``."""
    found = []
    for module, targets in sorted(graph.items()):
        here = layer_of(module)
        for target in sorted(targets):
            if target.split(".")[0] not in PACKAGES:
                continue
            there = layer_of(target)
            if there is not None and here is not None and ORDER.index(there) > ORDER.index(here):
                found.append(f"{module} ({here}) imports {target} ({there})")
            if target == "stiffnet.cli" and module != "stiffnet.__main__":
                found.append(f"{module} imports stiffnet.cli")
    return found


def reachable(graph: dict[str, set[str]], start: Iterable[str]) -> dict[str, str]:
    """Every module reachable from ``start``, each with the module that imports it."""
    seen: dict[str, str] = {}
    todo = list(start)
    while todo:
        module = todo.pop()
        for target in graph.get(module, ()):
            if target not in seen:
                seen[target] = module
                todo.append(target)
    return seen


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {
        name: imports_of(name, path.read_text(), path.name == "__init__.py", modules)
        for name, path in modules.items()
    }


def test_every_module_has_a_layer(graph: dict[str, set[str]]) -> None:
    assert len(graph) > 50  # the walk found the packages
    unplaced = [m for m in graph if layer_of(m) is None]
    assert not unplaced, f"add these modules to a layer in LAYERS (and the docs): {unplaced}"


def test_imports_run_one_way(graph: dict[str, set[str]]) -> None:
    bad = violations(graph)
    assert not bad, "imports against the layer rule:\n" + "\n".join(bad)


def test_predictor_never_reaches_training_libraries(graph: dict[str, set[str]]) -> None:
    serving = [m for m in graph if m == "serving" or m.startswith("serving.")]
    assert "serving.predictor" in serving
    seen = reachable(graph, serving)
    bad = [
        f"{target} (imported by {by})"
        for target, by in sorted(seen.items())
        if target.split(".")[0] in FORBIDDEN_IN_PREDICTOR
    ]
    assert not bad, "the predictor reaches " + ", ".join(bad)


def test_rule_checker_catches_upward_imports() -> None:
    # the checker itself: an upward import, an import of the CLI and a reach into torch
    known = {"stiffnet.cli", "stiffnet.nlts.delay", "serving.predictor", "training.cnn"}
    graph = {
        "stiffnet.nlts.delay": imports_of(
            "stiffnet.nlts.delay", "def f():\n    from stiffnet.cli import app\n", False, known
        ),
        "serving.predictor": imports_of(
            "serving.predictor", "from training import cnn\n", False, known
        ),
        "training.cnn": imports_of("training.cnn", "import torch.nn\n", False, known),
    }
    assert graph["serving.predictor"] == {"training.cnn"}
    bad = violations(graph)
    assert "stiffnet.nlts.delay (core) imports stiffnet.cli (cli)" in bad
    assert "stiffnet.nlts.delay imports stiffnet.cli" in bad
    assert reachable(graph, ["serving.predictor"]) == {
        "training.cnn": "serving.predictor",
        "torch.nn": "training.cnn",
    }
    # relative imports resolve against the package
    rel = imports_of("serving.app", "from .predictor import Predictor\n", False, known)
    assert rel == {"serving.predictor"}


# ---------------------------------------------------------------- model families

#: Where the model families live: one package each under training/families/, one module
#: each under serving/families/ (base.py is the contract, not a family).
FAMILY_HOMES = ("training/families", "serving/families")


def family_names(root: Path = ROOT) -> set[str]:
    """The families, from the file system: each one's training package and serving module."""
    training = {p.parent.name for p in (root / "training/families").glob("*/__init__.py")}
    serving = {p.stem for p in (root / "serving/families").glob("*.py")}
    return training | (serving - {"__init__", "base"})


def in_family_folder(path: Path, families: set[str], root: Path = ROOT) -> bool:
    rel = path.relative_to(root)
    parts = rel.with_suffix("").parts
    return any(
        "/".join(parts[:2]) == home and len(parts) > 2 and parts[2] in families
        for home in FAMILY_HOMES
    )


def words(text: str) -> set[str]:
    """Lower-case words of an identifier or a file-like string: snake, camel, dots, slashes."""
    spaced = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1 \2", text)  # GBMConfig -> GBM Config
    spaced = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", spaced)  # fitGbm -> fit Gbm
    return {w.lower() for w in re.split(r"[^A-Za-z0-9]+", spaced) if w}


def docstring_ids(tree: ast.AST) -> set[int]:
    """``id`` of every docstring node (module, class, function) of a parsed source."""
    return {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }


def family_mentions(source: str, families: set[str]) -> list[str]:
    """Code that names a family: identifiers, imports and identifier-like strings.

    Docstrings and prose strings (messages, help texts: they contain a space) may
    name a family as an example; code may not depend on one.
    """
    tree = ast.parse(source)
    docstrings = docstring_ids(tree)
    found = []
    for node in ast.walk(tree):
        texts: list[str] = []
        if isinstance(node, ast.Name):
            texts = [node.id]
        elif isinstance(node, ast.Attribute):
            texts = [node.attr]
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            texts = [node.name]
        elif isinstance(node, ast.arg):
            texts = [node.arg]
        elif isinstance(node, ast.keyword) and node.arg:
            texts = [node.arg]
        elif isinstance(node, ast.alias):
            texts = [node.name, node.asname or ""]
        elif isinstance(node, ast.ImportFrom):
            texts = [node.module or ""]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if id(node) not in docstrings and not re.search(r"\s", node.value):
                texts = [node.value]
        for text in texts:
            if words(text) & families:
                found.append(f"line {getattr(node, 'lineno', '?')}: {text!r}")
    return found


def test_no_module_outside_a_family_folder_names_a_family() -> None:
    families = family_names()
    assert {"cnn", "gbm"} <= families  # the walk found the shipped families
    bad = [
        f"{path.relative_to(ROOT)} {hit}"
        for path in all_modules().values()
        if not in_family_folder(path, families)
        for hit in family_mentions(path.read_text(), families)
    ]
    assert not bad, "only a family's own folder may name it (use the registry):\n" + "\n".join(bad)


def test_family_checker_catches_names() -> None:
    src = (
        '"""The gbm docstring may name one."""\n'
        "from training.families.gbm import GBMTraining\n"
        "x = cfg.cnn\n"
        'path = "train/gbm.yaml"\n'
        'msg = "use gbm or cnn"\n'
        "def fit_cnn(): pass\n"
    )
    hits = family_mentions(src, {"gbm", "cnn"})
    lines = sorted({int(h.split(":", 1)[0].removeprefix("line ")) for h in hits})
    assert lines == [2, 3, 4, 6]  # not the docstring (1) nor the message (5)
    assert words("GBMConfig") == {"gbm", "config"} and words("stiffnet.cnn") == {"stiffnet", "cnn"}
    assert in_family_folder(ROOT / "training/families/gbm/export.py", {"gbm"})
    assert in_family_folder(ROOT / "serving/families/cnn.py", {"cnn"})
    assert not in_family_folder(ROOT / "training/finish.py", {"gbm"})
