"""The one boundary for user input: documents, numbers, physical rates, knobs, output paths.

Everything a user hands to stiffnet (a JSON sidecar, card or ``--diagnosis`` file, a
YAML config, a number on the command line or in a request, an output path) passes
through one of these functions first, so that bad input is one clear
:class:`~stiffnet.errors.StiffnetError` line before any work starts, never a
traceback and never a silently wrong value. Rules:

* **Documents** are UTF-8, at most :data:`MAX_DOCUMENT_BYTES`, nested at most
  :data:`MAX_DEPTH` deep, with finite numbers only (``NaN``/``Infinity`` are not
  JSON, and an integer too large for a float is refused).
* **Numbers** are real numbers: ``true`` is not 1 and ``"1000"`` is not 1000.
* **Rates** lie in physical ranges (:data:`FS_RANGE_HZ`, :data:`FN_RANGE_HZ`,
  :data:`RATIO_RANGE` for ``fs / f_n``), so derived sizes (samples per window) stay finite.
* **Knobs** (threads, workers, budgets) are bounded by what the machine has.
* **Output paths** are checked before the work: a file target is a regular file
  or absent, in an existing folder; a folder target is a folder or absent.

numpy-free and light: the HTTP predictor imports it.
"""

from __future__ import annotations

import contextvars
import json
import math
import numbers
import os
import re
import stat
import tempfile
from pathlib import Path
from typing import Any

from stiffnet.errors import StiffnetError

#: Largest JSON or YAML document read (a card, sidecar or config is a few kB).
MAX_DOCUMENT_BYTES = 16 * 1024 * 1024
#: Deepest nesting of lists and objects in a document.
MAX_DEPTH = 64
#: Sampling rates accepted, Hz: from a slow logger to a fast digitiser.
FS_RANGE_HZ = (1e-2, 1e8)
#: Natural frequencies of a rig accepted, Hz.
FN_RANGE_HZ = (1e-3, 1e6)
#: Samples per natural period accepted (``fs / f_n``): below 1 nothing is resolved,
#: above 1e5 one 16-period window would hold over a million samples.
RATIO_RANGE = (1.0, 1e5)


def one_line(text: object, limit: int = 1000) -> str:
    """``text`` on one line: newlines and other control characters shown escaped."""
    s = str(text)
    out = "".join(
        ch if ch.isprintable() or ch == " " else ch.encode("unicode_escape").decode() for ch in s
    )
    return out if len(out) <= limit else out[: limit - 3] + "..."


#: What a message may quote from a file: a short word or number (a column name, a cell).
_QUOTABLE = re.compile(r"^[A-Za-z0-9_ .+\-]{0,32}$")


def quote_content(text: str, cells: int = 1) -> str | None:
    """``repr(text)`` if it is safe to quote in a message, else None.

    Errors never echo file contents: a file that is not what it should be (a link to
    a secret, a binary) shows up only as its shape. Short words and numbers, comma-
    separated into at most ``cells`` cells, are quoted, since they name the problem.
    """
    parts = text.split(",")
    if len(parts) <= cells and all(_QUOTABLE.match(c) for c in parts):
        return repr(text)
    return None


# ------------------------------------------------------------------------------ numbers


#: A number written with a unit after it ("9.48 Hz", "1 kHz", "2.8mm").
_NUMBER_WITH_UNIT = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*[A-Za-z/%°]+\s*$")


def unit_hint(value: Any) -> str:
    """What to write instead of a number given with its unit (``"9.48 Hz"``, ``"2.8mm"``):
    a hint to append to the refusal, empty for any other value.

    Parameters
    ----------
    value : Any
        The value refused as not a number.

    Returns
    -------
    str
        ``" (the number alone: the name carries the unit)"``, for a number written with a
        comma (``"9,48"``, a decimal comma or a thousands separator) what to write, or ``""``.
    """
    if isinstance(value, str) and _NUMBER_WITH_UNIT.match(value):
        return " (the number alone: the name carries the unit)"
    if isinstance(value, str) and _NUMBER_WITH_COMMA.match(value):
        # which the comma was is the writer's to say: a decimal comma or thousands
        return " (a comma in a number: write the decimal point '.' and no thousands separator)"
    return ""


#: A number written with a comma, as a lab's locale writes it ("9,48", "5000,0", "1,000").
_NUMBER_WITH_COMMA = re.compile(r"^\s*[-+]?\d+(,\d+)+\s*$")


#: Bytes read to find where a text file stops being UTF-8 (the message's line number).
_ENCODING_PROBE_BYTES = 1 << 20


def not_utf8_words(path: str | os.PathLike[str]) -> str:
    """Why a file that does not decode as UTF-8 does not, to append to the refusal: a UTF-16
    byte-order mark (Windows' "Unicode" text), else the first line holding a byte that is
    not UTF-8 (a Latin-1 or Windows-1252 accent, a binary file), within its first MiB.

    Parameters
    ----------
    path : str or os.PathLike
        The file refused.

    Returns
    -------
    str
        ``": ..."`` saying what was found and to save the file as UTF-8, or ``""``.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(_ENCODING_PROBE_BYTES)
    except OSError:
        return ""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return ": it is UTF-16 text, as Windows saves 'Unicode' text; save it as UTF-8"
    for number, line in enumerate(head.split(b"\n"), start=1):
        try:
            line.decode("utf-8")
        except UnicodeDecodeError as exc:
            if exc.reason == "unexpected end of data":  # the probe cut a character
                break
            return (
                f": line {number} holds a byte that is not UTF-8 (Latin-1 or Windows-1252 "
                "text, or a binary file); save it as UTF-8"
            )
    return ""


def without_unnamed_tail(header: list[str]) -> list[str]:
    """A CSV header without the unnamed cells that end it (``t,accel,,`` as a spreadsheet
    saves a sheet whose empty columns were once touched): nobody named them, so they are
    not columns (an unnamed cell before a named one still is).

    Parameters
    ----------
    header : list of str
        The header's cells as read.

    Returns
    -------
    list of str
        The cells up to the last named one (at least one cell).
    """
    n = len(header)
    while n > 1 and not header[n - 1].strip():
        n -= 1
    return header[:n]


def real_number(value: Any, what: str) -> float:
    """``value`` as a finite float; bools, strings and huge integers are refused."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # numpy scalars are Real
        raise StiffnetError(f"{what} must be a number, got {_show(value)}{unit_hint(value)}")
    try:
        v = float(value)
    except (OverflowError, ValueError, TypeError):
        raise StiffnetError(f"{what} is too large to be a number: {_show(value)}") from None
    if not math.isfinite(v):
        raise StiffnetError(f"{what} must be a finite number, got {_show(value)}")
    return v


def in_range(value: Any, what: str, lo: float, hi: float, unit: str = "") -> float:
    """A finite number in ``[lo, hi]`` (the message names the range)."""
    v = real_number(value, what)
    if not lo <= v <= hi:
        u = f" {unit}" if unit else ""
        raise StiffnetError(f"{what} must be in [{lo:g}, {hi:g}]{u}, got {v:.6g}{u}")
    return v


def sampling_rate(value: Any, what: str = "sampling rate fs_hz") -> float:
    """A sampling rate in :data:`FS_RANGE_HZ`."""
    return in_range(value, what, *FS_RANGE_HZ, unit="Hz")


def natural_frequency(value: Any, what: str = "natural_frequency_hz") -> float:
    """A natural frequency in :data:`FN_RANGE_HZ`."""
    return in_range(value, what, *FN_RANGE_HZ, unit="Hz")


def rate_ratio(fs_hz: float, fn_hz: float, what: str = "") -> float:
    """``fs / f_n`` checked against :data:`RATIO_RANGE` (both already range-checked)."""
    ratio = fs_hz / fn_hz
    lo, hi = RATIO_RANGE
    if not lo <= ratio <= hi:
        prefix = f"{what}: " if what else ""
        raise StiffnetError(
            f"{prefix}sampling rate {fs_hz:.6g} Hz is {ratio:.3g} x the natural frequency "
            f"{fn_hz:.6g} Hz; it must be {lo:g} to {hi:g} x"
        )
    return ratio


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def max_local_workers() -> int:
    """Most local Dask worker processes: 4 per core (each holds a simulator's memory)."""
    return 4 * available_cores()


def bounded_count(value: int | None, what: str, lo: int = 1, hi: int | None = None) -> int | None:
    """An integer knob in ``[lo, hi]`` (None passes through)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise StiffnetError(f"{what} must be an integer, got {_show(value)}")
    if value < lo or (hi is not None and value > hi):
        span = f"{lo}..{hi}" if hi is not None else f">= {lo}"
        raise StiffnetError(f"{what} must be {span}, got {value}")
    return value


def threads(value: int | None, what: str = "--threads") -> int | None:
    """A thread count: 1 to the number of available cores."""
    return bounded_count(value, what, 1, available_cores())


# ---------------------------------------------------------------------------- documents


def _show(value: Any) -> str:
    text = repr(value)
    return one_line(text if len(text) <= 40 else text[:37] + "...", 60)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > 300:  # beyond float range: 1e300 is the biggest sane value
        raise ValueError("integer too large for a number")
    return int(text)


def check_depth(obj: Any, what: str, limit: int = MAX_DEPTH) -> None:
    """Refuse lists/objects nested deeper than ``limit`` (iterative: no recursion)."""
    stack = [(obj, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            if depth > limit:
                raise StiffnetError(f"{what}: nested deeper than {limit} levels")
            children = item.values() if isinstance(item, dict) else item
            stack.extend((c, depth + 1) for c in children)


def _read_bounded(path: Path, what: str, limit: int) -> bytes:
    try:
        st = path.stat()
    except FileNotFoundError:
        raise StiffnetError(f"{path}: {what} not found") from None
    except OSError as exc:
        raise StiffnetError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        raise StiffnetError(f"{path}: the {what} is not a regular file")
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise StiffnetError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    if len(data) > limit:
        raise StiffnetError(f"{path}: the {what} is larger than {limit // (1024 * 1024)} MB")
    return data


def parse_json(data: bytes | str, what: str) -> Any:
    """Decode one JSON document under the rules of the module notes."""
    if isinstance(data, bytes):
        if len(data) > MAX_DOCUMENT_BYTES:
            raise StiffnetError(f"{what} is larger than {MAX_DOCUMENT_BYTES // 2**20} MB")
        try:
            data = data.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise StiffnetError(f"{what} is not UTF-8 text") from None
    # A quick bound on nesting before the (recursive) decoder sees the text.
    if data.count("[") + data.count("{") > MAX_DEPTH:
        depth = peak = 0
        for ch in data:
            if ch in "[{":
                depth += 1
                peak = max(peak, depth)
                if peak > MAX_DEPTH:
                    break
            elif ch in "]}":
                depth -= 1
        if peak > MAX_DEPTH:  # brackets in strings only make this conservative
            raise StiffnetError(f"{what}: nested deeper than {MAX_DEPTH} levels")
    try:
        obj = json.loads(data, parse_constant=_no_constant, parse_int=_bounded_int)
    except RecursionError:
        raise StiffnetError(f"{what}: nested deeper than {MAX_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        raise StiffnetError(
            f"{what} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None
    except ValueError as exc:
        raise StiffnetError(f"{what} is not valid JSON ({one_line(exc, 120)})") from None
    _check_floats(obj, what)
    return obj


def _check_floats(obj: Any, what: str) -> None:
    stack = [obj]
    while stack:
        item = stack.pop()
        if isinstance(item, float) and not math.isfinite(item):  # 1e400 parses as inf
            raise StiffnetError(f"{what}: a number is too large (beyond float range)")
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)


def read_json(path: str | os.PathLike[str], what: str = "JSON file") -> Any:
    """Read a JSON file (regular file, size-, depth- and number-checked)."""
    p = Path(path)
    return parse_json(_read_bounded(p, what, MAX_DOCUMENT_BYTES), f"{p}: {what}")


def read_json_object(path: str | os.PathLike[str], what: str = "JSON file") -> dict[str, Any]:
    """:func:`read_json` that must give an object."""
    obj = read_json(path, what)
    if not isinstance(obj, dict):
        raise StiffnetError(f"{path}: the {what} must be a JSON object, not {_kind(obj)}")
    return obj


def read_yaml_mapping(path: str | os.PathLike[str], what: str = "config") -> dict[str, Any]:
    """Read a YAML mapping with ``yaml.safe_load`` (empty file: ``{}``)."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise StiffnetError(f"{what} file not found: {p}")
    data = _read_bounded(p, f"{what} file", MAX_DOCUMENT_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise StiffnetError(f"{p}: the {what} file is not UTF-8 text") from None
    try:
        obj = yaml.load(text, Loader=_loader(yaml))  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark else ""
        if type(exc) is yaml.YAMLError:  # ours: the message says what
            raise StiffnetError(f"{p}: {exc}") from None
        raise StiffnetError(f"{p}: invalid YAML{line}") from None
    except RecursionError:
        raise StiffnetError(f"{p}: nested deeper than {MAX_DEPTH} levels") from None
    if obj is None:
        return {}
    if not isinstance(obj, dict):
        raise StiffnetError(
            f"{p}: the {what} must be a YAML mapping (key: value), not {_kind(obj)}"
        )
    check_depth(obj, str(p))
    _check_floats(obj, str(p))
    return obj


def _loader(yaml: Any) -> type:
    """``yaml.SafeLoader`` without anchors and aliases.

    An alias re-uses a node: a few hundred bytes of nested aliases ("billion laughs")
    expand to ~10^9 nodes for every walk over the document. Configs need neither.
    """

    class NoAliasLoader(yaml.SafeLoader):
        def compose_node(self, parent: Any, index: Any) -> Any:
            event = self.peek_event()
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise yaml.YAMLError(
                    f"YAML anchors and aliases (&, *) are not supported "
                    f"(line {event.start_mark.line + 1})"
                )
            return super().compose_node(parent, index)

    return NoAliasLoader


def _kind(obj: Any) -> str:
    return {list: "a list", str: "a string", int: "a number", float: "a number",
            bool: "a boolean", type(None): "null"}.get(type(obj), type(obj).__name__)  # fmt: skip


# ------------------------------------------------------------------------- output paths


def output_file(path: str | os.PathLike[str] | None, what: str = "--json") -> Path | None:
    """Check an output file path before any work (see the module notes)."""
    if path is None:
        return None
    p = path_name(path, what)
    if "\n" in str(p) or "\r" in str(p):
        raise StiffnetError(f"{what} {one_line(p)}: a file name with a line break")
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise StiffnetError(f"{what} {p}: cannot use this path ({exc.strerror})") from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        if stat.S_ISLNK(st.st_mode):
            kind = "a symbolic link"
        raise StiffnetError(f"{what} {p}: is {kind}; give a regular file path")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise StiffnetError(f"{what} {p}: folder {parent} does not exist (create it first)")
    try:  # the atomic write creates a temporary file there: try it now, not after the work
        fd, probe = tempfile.mkstemp(prefix=f".{p.name[:100]}.", suffix=".probe", dir=parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise StiffnetError(f"{what} {p}: cannot write in {parent} ({exc.strerror})") from None
    return p


def output_folder(path: str | os.PathLike[str] | None, what: str = "--out") -> Path | None:
    """Check an output folder path before any work: a folder, or absent under a folder."""
    if path is None:
        return None
    p = path_name(path, what)
    if "\n" in str(p) or "\r" in str(p):
        raise StiffnetError(f"{what} {one_line(p)}: a folder name with a line break")
    if p.is_symlink() or (p.exists() and not p.is_dir()):
        raise StiffnetError(f"{what} {p}: exists and is not a folder")
    anchor = p
    while not anchor.exists():  # the nearest existing ancestor must be a writable folder
        if anchor.parent == anchor:
            break
        anchor = anchor.parent
    if not anchor.is_dir():
        raise StiffnetError(f"{what} {p}: {anchor} is not a folder")
    _probe_folder(anchor, p, what)  # /proc says writable to os.access, and is not
    return p


def _probe_folder(folder: Path, p: Path, what: str) -> None:
    """Create and remove a temporary folder in ``folder``: it is writable now, not later."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=f".{p.name[:40]}.", suffix=".probe", dir=folder))
    except OSError as exc:
        raise StiffnetError(f"{what} {p}: cannot write in {folder} ({exc.strerror})") from None


#: Longest file or folder name (bytes) on the usual file systems.
MAX_NAME_BYTES = 255


def path_name(path: str | os.PathLike[str], what: str) -> Path:
    """``path`` if every part of it is a usable name (no NUL, each part <= 255 bytes)."""
    text = os.fspath(path)
    if "\x00" in text:
        raise StiffnetError(f"{what} {one_line(text, 80)}: a path with a NUL byte")
    for part in Path(text).parts:
        if len(part.encode("utf-8", "surrogateescape")) > MAX_NAME_BYTES:
            raise StiffnetError(f"{what} {one_line(part, 60)}: a name longer than "
                                f"{MAX_NAME_BYTES} bytes")  # fmt: skip
    return Path(text)


# ------------------------------------------------------------------ outputs vs inputs


def _real(p: Path) -> Path:
    try:
        return p.resolve()
    except (OSError, RuntimeError):  # a link loop: compare by name
        return Path(os.path.abspath(p))


def check_outputs(outputs: dict[str, tuple[Path, str]], inputs: dict[str, Path]) -> None:
    """Refuse outputs that would land on an input, inside one, or on each other.

    ``outputs``: flag -> (path, ``"file"`` or ``"folder"``); ``inputs``: name -> path of
    a recording, campaign, manifest, dataset, config, model or result the command reads.
    An output file may not be an input file nor replace the data of an input folder
    (a recording, its sidecar, a manifest, config, model or shard: :func:`_input_data`;
    an earlier report or JSON result there may be replaced);
    an output folder may not be, hold, or lie inside an input folder's files it would
    replace; two outputs may not be the same path.
    """
    seen: dict[Path, str] = {}
    ins = {name: _real(p) for name, p in inputs.items() if p is not None}
    for flag, (path, kind) in outputs.items():
        real = _real(path)
        if real in seen:
            raise StiffnetError(f"{flag} {path}: is also {seen[real]}; give two different paths")
        seen[real] = flag
        for name, src in ins.items():
            if real == src:
                raise StiffnetError(f"{flag} {path}: is the input {name}; choose another output")
            if kind == "folder" and src.is_relative_to(real):
                raise StiffnetError(f"{flag} {path}: holds the input {name} ({inputs[name]}); "
                                    "choose another output folder")  # fmt: skip
            inside = real.is_relative_to(src) and src.is_dir()
            if inside and kind == "file" and os.path.lexists(path) and _input_data(Path(path)):
                raise StiffnetError(f"{flag} {path}: would replace a file of the input {name} "
                                    f"({inputs[name]}); choose another output")  # fmt: skip


#: What an output may replace inside an input folder: an earlier report, figure or
#: JSON result. Anything else there (recordings of any format, manifests, configs,
#: models, shards, a user's own files) is the input's data and is never replaced.
_RESULT_SUFFIXES = (".json", ".html", ".png", ".svg")
_DATA_JSON = ("card.json", "campaign_card.json", "job.json", "stiffnet-run.json",
              "ood_reference.json", "geometric_calibration.json")  # fmt: skip


def _input_data(path: Path) -> bool:
    """Whether ``path`` (in an input folder) is data the input is made of."""
    name = path.name.lower()
    if path.suffix.lower() not in _RESULT_SUFFIXES:
        return True
    if name in _DATA_JSON or name.endswith(".card.json"):
        return True
    return name.endswith(".json") and path.with_suffix("").exists()  # a recording's sidecar


#: Kind of the marker (``stiffnet-run.json``) of a figure folder stiffnet wrote.
FIGURES_KIND = "stiffnet-figures"


def figure_folder(path: str | os.PathLike[str] | None, what: str = "--plots") -> Path | None:
    """A ``--plots`` folder: absent, empty, or one stiffnet wrote figures into before.

    Figures replace files of fixed names: in a user's folder they would overwrite a
    ``force_displacement.png`` of the user's. :func:`mark_figure_folder` marks it first.
    """
    from stiffnet.io_utils import RUN_MARKER, read_marker

    p = output_folder(path, what)
    if p is None or not p.is_dir() or not any(p.iterdir()):
        return p
    marker = read_marker(p / RUN_MARKER)
    if marker is None or marker.get("kind") != FIGURES_KIND:
        raise StiffnetError(f"{what} {p}: folder holds files stiffnet did not write (no "
                            f"{RUN_MARKER}); give a new or empty folder")  # fmt: skip
    return p


def mark_figure_folder(path: Path) -> None:
    """Create ``path`` (checked by :func:`figure_folder`) and mark it as stiffnet's figures."""
    from stiffnet.io_utils import RUN_MARKER, new_marker, read_marker, write_json_atomic

    path.mkdir(parents=True, exist_ok=True)
    if read_marker(path / RUN_MARKER) is None:
        write_json_atomic(path / RUN_MARKER, new_marker(FIGURES_KIND))


# ------------------------------------------------------------------------ seeds and URIs

#: Seeds numpy's generators take: 0 to 2**32 - 1 (a negative seed is an error there).
SEED_RANGE = (0, 2**32 - 1)


def seed(value: int | None, what: str = "--seed") -> int | None:
    """A random seed in :data:`SEED_RANGE` (None passes through)."""
    return bounded_count(value, what, *SEED_RANGE)


#: Seconds to wait for a remote MLflow tracking server before refusing it.
TRACKING_TIMEOUT_S = 3.0
_DB_SCHEMES = ("postgresql", "mysql", "mssql")


def tracking_uri(uri: str | None, what: str = "--tracking-uri") -> str | None:
    """Check an MLflow tracking URI before any work: scheme, writable store, reachable server.

    ``sqlite:///PATH`` (the folder exists and is writable, PATH a regular file or
    absent), ``file:///FOLDER`` or a plain folder (a folder, writable), ``http(s)://``
    (a TCP connection within :data:`TRACKING_TIMEOUT_S`), or a database URL
    (``postgresql://`` ...: reachable). An unreachable server is an
    :class:`~stiffnet.errors.EnvironmentFailure` (exit 1), a bad URI an error (exit 2).
    """
    from urllib.parse import unquote, urlsplit

    from stiffnet.errors import EnvironmentFailure

    if uri is None:
        return None
    text = one_line(uri, 200)
    if not uri.strip() or "\x00" in uri or "\n" in uri:
        raise StiffnetError(f"{what} {text!r}: not a tracking URI")
    parts = urlsplit(uri)
    scheme = parts.scheme.lower()
    if scheme == "sqlite":
        if not uri.startswith("sqlite:///"):
            raise StiffnetError(f"{what} {text}: write sqlite:///relative.db or "
                                "sqlite:////absolute/path.db")  # fmt: skip
        db = path_name(unquote(uri[len("sqlite:///") :]), what)
        if str(db) in ("", ".") or str(db).startswith(":memory:"):
            raise StiffnetError(f"{what} {text}: name a database file")
        output_file(db, f"{what} database")
        return uri
    if scheme in ("", "file"):
        folder = path_name(unquote(parts.path) if scheme else uri, what)
        if folder.exists() and not folder.is_dir():
            raise StiffnetError(f"{what} {text}: {folder} is not a folder (an MLflow file "
                                "store is a folder)")  # fmt: skip
        output_folder(folder, what)
        return uri
    if scheme in ("http", "https", *_DB_SCHEMES) or scheme.split("+")[0] in _DB_SCHEMES:
        import socket

        host = parts.hostname
        try:
            port = parts.port or {"http": 80, "https": 443}.get(scheme, 5432)
        except ValueError:
            raise StiffnetError(f"{what} {text}: invalid port") from None
        if not host:
            raise StiffnetError(f"{what} {text}: no host")
        try:
            socket.create_connection((host, port), timeout=TRACKING_TIMEOUT_S).close()
        except (OSError, UnicodeError) as exc:
            why = getattr(exc, "strerror", None) or type(exc).__name__
            raise EnvironmentFailure(f"{what} {text}: tracking server not reachable within "
                                     f"{TRACKING_TIMEOUT_S:g} s ({why})") from None  # fmt: skip
        return uri
    raise StiffnetError(f"{what} {text}: unsupported scheme {scheme!r} (use sqlite:///FILE.db, "
                        "a folder, file:///FOLDER or http(s)://HOST:PORT)")  # fmt: skip


# ------------------------------------------------------------------------------ hints

#: Where the user gives a recording's layout: "cli" (--columns, --time-unit),
#: "manifest" (its columns/time_unit columns) or "http" (form fields). The command
#: wrapper and the HTTP app set it; hints then name what the user can actually type.
HINT_CONTEXT: contextvars.ContextVar[str] = contextvars.ContextVar("hint_context",
                                                                  default="cli")  # fmt: skip
_SAFE_IN_DOUBLE_QUOTES = re.compile(r'^[^"$`\\!]*$')


def shell_quote(text: str) -> str:
    """``text`` as one shell word a user can paste (double quotes where they suffice)."""
    import shlex

    if re.fullmatch(r"[A-Za-z0-9_.,:/+\-=]+", text):
        return text
    if _SAFE_IN_DOUBLE_QUOTES.match(text):
        return f'"{text}"'
    return shlex.quote(text)


def where_given(cli: str, manifest: str, http: str) -> str:
    """How the user gives a value where they are (:data:`HINT_CONTEXT`): the command's
    option, the manifest's column or the HTTP field, so that a hint never names what the
    user cannot type (an HTTP client has no ``--fn``)."""
    return {"cli": cli, "manifest": manifest, "http": http}[HINT_CONTEXT.get()]


def sensor_given() -> str:
    """Where the user gives the accelerometer's data sheet (an HTTP client has no option)."""
    return where_given("--sensor", "the manifest's column sensor", "the field sensor")


def columns_hint(columns: str, time_unit: str | None = None) -> str:
    """How to name a CSV's columns (``"TIME,ACCEL"``) where the user gives them."""
    where = HINT_CONTEXT.get()
    if where == "manifest":
        unit = f" and time_unit {time_unit}" if time_unit else ""
        return f"name its columns in the manifest: columns {shell_quote(columns)}{unit}"
    if where == "http":
        unit = f" and time_unit={time_unit}" if time_unit else ""
        return f"name its columns: form field columns={columns}{unit}"
    unit = f" --time-unit {time_unit}" if time_unit else ""
    return f"name its columns: --columns {shell_quote(columns)}{unit}"


def mpl_text(text: object) -> str:
    """``text`` safe for a matplotlib title or label: ``$`` shown, not mathtext."""
    return one_line(text, 200).replace("\\", "\\\\").replace("$", r"\$")


def check_fields(data: dict[str, Any], spec: dict[str, tuple[type, ...]], where: str) -> None:
    """Optional ``data`` keys have the JSON types of ``spec`` (a bool is not a number).

    A list type in ``spec`` given as ``(list, str)`` means a list of strings.
    """
    for key, kinds in spec.items():
        if key not in data:
            continue
        value = data[key]
        items = kinds[1:] if kinds[0] is list and len(kinds) > 1 else None
        ok = isinstance(value, list) if items else isinstance(value, kinds)
        if ok and items:
            ok = all(isinstance(v, items) and not isinstance(v, bool) for v in value)
        if not ok or (isinstance(value, bool) and bool not in kinds):
            raise StiffnetError(f"{where}: key {key!r} is {_kind(value)}, not the expected type")


# ---------------------------------------------------------------------------- file walks

#: Most folder entries one walk looks at (a folder or glob of recordings): beyond it the
#: walk stops with an error instead of running on (``/proc/**``).
MAX_WALK_ENTRIES = 200_000
_MAGIC = re.compile(r"[*?\[]")


def _part_regex(part: str) -> str:
    out, i = [], 0
    while i < len(part):
        c = part[i]
        if c == "*":
            out.append("[^/]*")
        elif c == "?":
            out.append("[^/]")
        elif c == "[" and "]" in part[i + 2 :]:
            j = part.index("]", i + 2)
            body = part[i + 1 : j].replace("\\", "\\\\")
            out.append(f"[{'^' + body[1:] if body.startswith('!') else body}]")
            i = j
        else:
            out.append(re.escape(c))
        i += 1
    return "".join(out)


def walk_files(spec: str, what: str = "recordings", limit: int = MAX_WALK_ENTRIES) -> list[Path]:
    """Files named by a folder (searched recursively), a glob (``**`` included) or one file.

    Symbolic links to folders are not followed, and at most ``limit`` entries are
    looked at: a glob over ``/proc`` or a huge tree is one error line, not a hang.
    """
    root = Path(spec)
    if root.is_file():
        return [root]
    if root.is_dir():
        base, regex, depth = root, None, None
    else:
        parts = root.parts
        first = next((i for i, p in enumerate(parts) if _MAGIC.search(p)), None)
        if first is None:
            return []
        base = Path(*parts[:first]) if first else Path(".")
        rest = parts[first:]
        regex = re.compile("/".join("(?:[^/]+/)*[^/]+" if p == "**" else _part_regex(p)
                                    for p in rest).replace("(?:[^/]+/)*[^/]+/", "(?:[^/]+/)*")
                           + r"\Z")  # fmt: skip
        depth = None if "**" in rest else len(rest)
    found: list[Path] = []
    seen = 0
    stack = [(base, 0)]
    while stack:
        folder, level = stack.pop()
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue  # unreadable folders are skipped, as glob does
        seen += len(entries)
        if seen > limit:
            raise StiffnetError(f"{what} {one_line(spec, 200)}: more than {limit} entries under "
                                f"{base}; name a smaller folder or a narrower glob")  # fmt: skip
        for entry in entries:
            path = Path(entry.path)
            try:
                is_dir, is_file = entry.is_dir(follow_symlinks=False), entry.is_file()
            except OSError:  # a dangling or forbidden link: not a recording
                continue
            if is_dir:
                if depth is None or level + 1 < depth:
                    stack.append((path, level + 1))
            elif is_file:
                rel = path.relative_to(base).as_posix()
                if regex is None or regex.match(rel):
                    found.append(path)
    return found
