"""The one plugin discovery (stiffnet.plugins) that families, formats and effects share."""

import sys
import textwrap

import pytest

from stiffnet.plugins import defined_subclasses, discover, member_modules, once


@pytest.fixture
def toy_package(tmp_path, monkeypatch):
    """A package `toyplug`: a contract, two members (one a folder), and what is not a member."""
    root = tmp_path / "toyplug"
    (root / "folder").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "base.py": """
            import abc
            class Base(abc.ABC):
                @abc.abstractmethod
                def run(self): ...
            class Ready(Base):  # defined in the contract: not a member
                def run(self): return 0
            """,
        "zeta.py": """
            from toyplug.base import Base
            from toyplug.alpha import Alpha  # imported: found in alpha, not here
            class Zeta(Base):
                def run(self): return 2
            """,
        "alpha.py": """
            import abc
            from toyplug.base import Base
            class Alpha(Base):
                def run(self): return 1
            Alias = Alpha  # an alias is not a second member
            class _Hidden(Base):
                def run(self): return -1
            class Half(Base):  # abstract: not a member
                pass
            class Unrelated:
                pass
            """,
        "_helpers.py": """
            from toyplug.base import Base
            class Helper(Base):
                def run(self): return -2
            """,
        "folder/__init__.py": """
            from toyplug.base import Base
            class InFolder(Base):
                def run(self): return 3
            """,
    }
    for name, text in files.items():
        (root / name).write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "toyplug"
    for name in [m for m in sys.modules if m == "toyplug" or m.startswith("toyplug.")]:
        del sys.modules[name]


def test_members_are_the_concrete_classes_each_module_defines(toy_package):
    from toyplug.base import Base

    names = [c.__name__ for c in discover(toy_package, Base)]
    assert names == ["Alpha", "InFolder", "Zeta"]  # by module name: alpha, folder, zeta
    assert [c().run() for c in discover(toy_package, Base)] == [1, 3, 2]


def test_folders_only_and_a_given_order(toy_package):
    from toyplug.base import Base

    assert [c.__name__ for c in discover(toy_package, Base, packages_only=True)] == ["InFolder"]
    first_zeta = discover(toy_package, Base, order=lambda n: (n != "zeta", n))
    assert [c.__name__ for c in first_zeta] == ["Zeta", "Alpha", "InFolder"]
    modules = [m.__name__ for m in member_modules(toy_package)]
    assert modules == ["toyplug.alpha", "toyplug.folder", "toyplug.zeta"]  # no base, no _helpers


def test_defined_subclasses_of_one_module(toy_package):
    import toyplug.alpha
    from toyplug.base import Base

    assert defined_subclasses(toyplug.alpha, Base) == [toyplug.alpha.Alpha]


def test_the_registries_find_the_shipped_members():
    from serving.families import families
    from stiffnet.recordings.registry import discover_readers
    from training.families import families as training_families

    assert {"cnn", "gbm"} <= set(training_families())
    assert {"stiffnet.cnn", "stiffnet.gbm"} <= set(families())  # by their model_kind
    exts = [e for r in discover_readers() for e in r.extensions]
    assert exts[0] == ".csv" and {".npy", ".wav", ".tdms"} <= set(exts)


def test_discovery_runs_once_even_when_a_member_asks_again():
    calls = []

    @once
    def discover_members():
        calls.append(1)
        discover_members()  # a member module asking the registry while it is imported

    discover_members()
    discover_members()
    assert calls == [1]
