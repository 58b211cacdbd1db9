"""Configuration models (pydantic): the single source of truth for defaults and ranges."""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from stiffnet.errors import ConfigError

M = TypeVar("M", bound=BaseModel)


def validation_message(exc: ValidationError, source: str = "") -> str:
    """One line naming the offending field and what is wrong with it."""
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err["loc"])
    msg = err["msg"].removeprefix("Value error, ")
    prefix = f"{source}: " if source else ""
    more = f" (and {len(exc.errors()) - 1} more)" if len(exc.errors()) > 1 else ""
    return f"{prefix}{where + ': ' if where else ''}{msg}{more}"


def validate_config(model: type[M], data: Any, source: str = "") -> M:
    """Validate ``data`` against ``model``, raising a one-line :class:`ConfigError`."""
    try:
        return model.model_validate(data or {})
    except ValidationError as exc:
        raise ConfigError(validation_message(exc, source)) from None


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML config: a UTF-8 mapping, size- and depth-bounded (:mod:`stiffnet.inputs`)."""
    from stiffnet.errors import StiffnetError
    from stiffnet.inputs import read_yaml_mapping

    try:
        return read_yaml_mapping(path, "config")
    except ConfigError:
        raise
    except StiffnetError as exc:
        raise ConfigError(str(exc)) from None


def load_config(model: type[M], path: str | Path) -> M:
    """Load and validate a YAML config file."""
    return validate_config(model, load_yaml(path), str(path))


def shipped_settings(model: type[M], name: str) -> M:
    """``model`` validated from the shipped ``configs/<name>`` (one-line :class:`ConfigError`
    when invalid), else its defaults where the file is not there (an installed package
    without the repository's ``configs/``)."""
    from stiffnet.shipped import default_config

    path = default_config(name)
    return load_config(model, path) if path.is_file() else model()
