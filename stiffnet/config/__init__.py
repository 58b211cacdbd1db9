"""Configuration models (pydantic): the single source of truth for defaults and ranges."""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
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


def load_yaml(path: str | Path) -> Any:
    """Read a YAML file with a clear error for a missing or malformed file."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"config file not found: {path}")
    try:
        return yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark else ""
        raise ConfigError(f"{path}: invalid YAML{line}") from None


def load_config(model: type[M], path: str | Path) -> M:
    """Load and validate a YAML config file."""
    return validate_config(model, load_yaml(path), str(path))
