"""``topomap --help`` kept between commands, so that it prints without importing Hydra.

Composing the help imports Hydra and OmegaConf, stores every component's config and composes
``conf/`` -- most of a second -- and prints the same text every time until something it is made
of changes.  :func:`kept_help` returns the text printed last time when its key still matches:
topomap's and Python's versions and source files (:func:`~topomap.app.compose.schema_cache.
source_stamp`), the config files of ``conf/``, the plugins installed under the entry-point group
(their names, targets, distributions' versions and module files) and whether their autoload is
off.  Only a bare ``topomap --help`` (or ``-h``) is kept: with overrides the command line is
checked as for a run.  The file sits beside the schema cache (``TOPOMAP_CACHE_DIR``; ``""``
keeps none).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import sys
from pathlib import Path

__all__ = ["HELP_ARGS", "help_file", "kept_help", "keeping_help"]

#: the command lines whose output is kept (nothing else on the line)
HELP_ARGS = (["--help"], ["-h"])


def _stat_line(path: Path) -> str:
    try:
        st = path.stat()
    except OSError:
        return f"{path} -\n"
    return f"{path} {st.st_size} {st.st_mtime_ns}\n"


def _plugins_stamp(h) -> None:
    from importlib.metadata import entry_points
    from importlib.util import find_spec

    from .registry import AUTOLOAD_ENV, ENTRY_POINT_GROUP

    h.update(f"autoload-off={os.environ.get(AUTOLOAD_ENV, '')}\n".encode())
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: (e.name, e.value)):
        dist = getattr(ep, "dist", None)
        version = f"{dist.name} {dist.version}" if dist is not None else "-"
        h.update(f"{ep.name} {ep.value} {version}\n".encode())
        try:
            spec = find_spec(ep.module)
        except (ImportError, ValueError):
            spec = None
        if spec is not None and spec.origin:
            h.update(_stat_line(Path(spec.origin)).encode())


def help_file() -> Path | None:
    """Where the help text of this installation, config and plugins is kept (None: no cache)."""
    from .schema_cache import cache_file, source_stamp

    schemas = cache_file()
    if schemas is None:
        return None
    h = hashlib.sha256(source_stamp().encode())
    from ... import conf  # the package of conf/ (command_line.CONFIG_MODULE)

    for path in sorted(Path(conf.__file__).parent.rglob("*.yaml")):
        h.update(_stat_line(path).encode())
    _plugins_stamp(h)
    return schemas.with_name(f"help-{h.hexdigest()[:20]}.txt")


def kept_help(argv: list[str]) -> str | None:
    """The help text printed for ``argv`` last time, if it is a bare ``--help`` and nothing it
    is made of changed since; else None."""
    if argv not in HELP_ARGS:
        return None
    path = help_file()
    try:
        return path.read_text() if path is not None else None
    except OSError:
        return None


class _Tee(io.TextIOBase):
    def __init__(self, out, copy: io.StringIO):
        self.out, self.copy = out, copy

    def write(self, text: str) -> int:
        self.copy.write(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


@contextlib.contextmanager
def keeping_help(argv: list[str]):
    """Around the command: for a bare ``--help``, what it prints is kept when it ends well
    (returns or exits with 0), written whole or not at all."""
    if argv not in HELP_ARGS:
        yield
        return
    copy = io.StringIO()
    ok = False
    try:
        with contextlib.redirect_stdout(_Tee(sys.stdout, copy)):
            yield
        ok = True
    except SystemExit as exc:
        ok = exc.code in (None, 0)
        raise
    finally:
        if ok and copy.getvalue():
            _write(copy.getvalue())


def _write(text: str) -> None:
    from ...core.data.atomic import atomic_write

    path = help_file()
    if path is None:
        return
    try:
        atomic_write(path, lambda tmp: tmp.write_text(text))
    except OSError:  # a read-only home: compose it again next time
        pass
