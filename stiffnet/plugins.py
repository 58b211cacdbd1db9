"""Plugin discovery, pysindy style: a package's modules, each contributing the classes it defines.

The model families the predictor serves (:mod:`serving.families`), the families
training knows (:mod:`training.families`), the recording formats
(:mod:`stiffnet.recordings.registry`) and the effects loaded from plugin files
(:func:`stiffnet.effects.registry.user_effects`) are all found the same way: every
module of a package (``base`` is the contract, ``_private`` modules are helpers) is
imported, and the concrete subclasses of the contract's base class that the module
*defines* (not those it imports) are its members. Adding a member is adding a
module; nothing lists the members by hand.

Standard library only: the predictor imports it.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import pkgutil
from collections.abc import Callable
from types import ModuleType
from typing import Any, TypeVar

T = TypeVar("T")

#: Module names that are never members: the contract itself.
CONTRACT_MODULES = frozenset({"base"})


def once(fn: Callable[[], None]) -> Callable[[], None]:
    """`fn` (a registry's discovery) runs at its first call only; it counts as done from
    the moment it starts, so a member module that asks the registry while discovery
    imports it does not start discovery again."""
    done = False

    @functools.wraps(fn)
    def run() -> None:
        nonlocal done
        if not done:
            done = True
            fn()

    return run


def defined_subclasses(module: ModuleType, base: type[T]) -> list[type[T]]:
    """The concrete public subclasses of `base` that `module` defines, by attribute name.

    A class the module merely imports is left out (each member is found once, in the
    module that defines it, under its own name: an alias is not a second member), as are
    `base` itself, abstract classes and ``_private`` names.
    """
    return [
        obj
        for attr, obj in sorted(vars(module).items())
        if isinstance(obj, type)
        and issubclass(obj, base)
        and obj is not base
        and attr == obj.__name__
        and not attr.startswith("_")
        and not inspect.isabstract(obj)
        and obj.__module__ == module.__name__
    ]


def member_modules(
    package: str | ModuleType,
    *,
    packages_only: bool = False,
    order: Callable[[str], Any] | None = None,
) -> list[ModuleType]:
    """Import every member module of `package` (its contract and ``_private`` ones left out).

    `packages_only` keeps subpackages only (a family that is a folder); `order` sorts
    the module names (default: by name).
    """
    pkg = importlib.import_module(package) if isinstance(package, str) else package
    names = [
        info.name
        for info in pkgutil.iter_modules(pkg.__path__)
        if not info.name.startswith("_")
        and info.name not in CONTRACT_MODULES
        and (info.ispkg or not packages_only)
    ]
    names.sort(key=order)
    return [importlib.import_module(f"{pkg.__name__}.{name}") for name in names]


def discover(
    package: str | ModuleType,
    base: type[T],
    *,
    packages_only: bool = False,
    order: Callable[[str], Any] | None = None,
) -> list[type[T]]:
    """The members of `package`: each member module's :func:`defined_subclasses` of `base`.

    Parameters
    ----------
    package : str or module
        The package whose modules are walked (``"stiffnet.recordings"``).
    base : type
        The contract's base class.
    packages_only, order
        As in :func:`member_modules`.
    """
    return [
        cls
        for module in member_modules(package, packages_only=packages_only, order=order)
        for cls in defined_subclasses(module, base)
    ]
