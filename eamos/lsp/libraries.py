"""Mission libraries as the editor sees them: what ``import "`` may name, what ``pkg.`` offers.

The folders searched and their order are the compiler's own
(:func:`eamos.compiler.libraries.search_path`: the mission's folder, each folder of
``EAMOS_PATH``, the shipped standard library), and an imported library's blocks are
read by the compiler's own loader (:func:`eamos.compiler.libraries.load_libraries`),
so the editor offers exactly what ``eamos compile`` would find.  Pure functions of
the file system at the moment of the call; nothing is cached here (the document's
index caches per text).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..compiler import MissionError
from ..compiler.libraries import load_libraries, search_path
from ..compiler.syntax import Block, Mission

Origin = Literal["mission folder", "EAMOS_PATH", "standard library"]

#: What ``import "..."`` accepts: folder names of letters, digits and ``_``, ``/`` between.
LIBRARY_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
#: How deep below a search folder a library folder is looked for (``a/b/c``).
MAX_DEPTH = 3
#: At most this many folders are looked at per search folder (a home folder on EAMOS_PATH
#: must not make completion walk the whole disk).
MAX_FOLDERS = 2000


@dataclass(frozen=True)
class Library:
    """A library an ``import`` can name: its name, its folder and where that was found."""

    name: str
    folder: Path
    origin: Origin


@dataclass(frozen=True)
class LibraryBlock:
    """A block of an imported library: ``shapes.SEQ_Square(d fleet.Flyer, side_m float64)``."""

    package: str
    name: str
    params: tuple[tuple[str, str], ...]  # (name, type) in order
    file: str
    line: int  # 1-based, of the block's name in ``file``
    col: int
    doc: str = ""  # the comment lines just above its ``func``

    @property
    def signature(self) -> str:
        """How it is called, with its parameters' names and types."""
        params = ", ".join(f"{n} {t}" for n, t in self.params)
        return f"{self.package}.{self.name}({params})"

    @property
    def snippet(self) -> str:
        """The call with one placeholder per parameter (after ``package.``)."""
        holes = ", ".join(f"${{{i}:{n}}}" for i, (n, _) in enumerate(self.params, start=1))
        return f"{self.name}({holes})"

    def help(self) -> str:
        """Markdown help: the signature, its comment, where it is defined."""
        parts = [f"```go\n{self.signature}\n```"]
        if self.doc:
            parts.append(self.doc)
        parts.append(f"Defined in `{self.file}`, line {self.line}.")
        return "\n\n".join(parts)


def mission_folder(path: str) -> Path | None:
    """The folder a mission's imports are looked up in first (None for an unsaved text)."""
    return None if path in ("", "<mission>") else Path(path).parent


def _origin(i: int, count: int, has_mission_dir: bool) -> Origin:
    if i == count - 1:
        return "standard library"
    return "mission folder" if i == 0 and has_mission_dir else "EAMOS_PATH"


def _library_folders(base: Path) -> list[tuple[str, Path]]:
    """Folders below ``base`` (to :data:`MAX_DEPTH`) holding ``.go`` files, by import name."""
    found: list[tuple[str, Path]] = []
    level = [(base, "")]
    seen = 0
    for _ in range(MAX_DEPTH):
        below: list[tuple[Path, str]] = []
        for folder, prefix in level:
            try:
                children = sorted(p for p in folder.iterdir() if p.is_dir())
            except OSError:
                continue  # unreadable or gone: the compiler would not find it either
            for child in children:
                seen += 1
                if seen > MAX_FOLDERS:
                    return found
                name = f"{prefix}{child.name}"
                if not LIBRARY_NAME.fullmatch(name):
                    continue  # .git, __pycache__, names an import cannot spell
                if any(child.glob("*.go")):
                    found.append((name, child))
                below.append((child, f"{name}/"))
        level = below
    return found


def available_libraries(path: str, environ: Mapping[str, str] | None = None) -> list[Library]:
    """Every library ``import "NAME"`` would find for the mission at ``path``, by name.

    A name found in two folders is listed once, from the first folder in the
    compiler's order (the one the compiler would load).
    """
    folders = search_path(mission_folder(path), environ)
    has_dir = mission_folder(path) is not None
    out: dict[str, Library] = {}
    for i, base in enumerate(folders):
        origin = _origin(i, len(folders), has_dir)
        for name, folder in _library_folders(base):
            out.setdefault(name, Library(name, folder, origin))
    return sorted(out.values(), key=lambda lib: lib.name)


def _doc_comment(text: str, line: int) -> str:
    """The ``//`` comment lines right above line ``line`` (1-based) of ``text``, as prose."""
    lines = text.splitlines()
    at = line - 2
    out: list[str] = []
    while 0 <= at < len(lines) and lines[at].lstrip().startswith("//"):
        out.append(lines[at].lstrip()[2:].strip())
        at -= 1
    return " ".join(reversed(out)).strip()


def _block(package: str, block: Block, texts: Mapping[str, str]) -> LibraryBlock:
    name = block.name.split(".", 1)[1]
    file = block.loc.file
    return LibraryBlock(
        package,
        name,
        tuple((p.name, p.type) for p in block.params),
        file,
        block.loc.line,
        block.loc.col,
        _doc_comment(texts.get(file, ""), block.loc.line),
    )


def imported_blocks(
    mission: Mission, path: str, environ: Mapping[str, str] | None = None
) -> dict[str, tuple[LibraryBlock, ...]]:
    """The blocks of each library the mission imports itself, by package name.

    Loaded as the compiler loads them; a library that cannot be found or read
    has no blocks here (the compiler's diagnostics say why).  Libraries that
    only other libraries import are not listed: the mission cannot call them.
    """
    direct = {imp.path.rsplit("/", 1)[-1] for imp in mission.imports}
    if not direct:
        return {}
    try:
        loaded = load_libraries(mission, mission_folder(path), environ)
    except (MissionError, OSError):
        return {p: () for p in sorted(direct)}
    found: dict[str, list[LibraryBlock]] = {p: [] for p in sorted(direct)}
    for qualified, block in loaded.mission.blocks.items():
        package = qualified.split(".", 1)[0]
        if "." in qualified and package in found:
            found[package].append(_block(package, block, loaded.texts))
    return {p: tuple(sorted(blocks, key=lambda b: b.name)) for p, blocks in found.items()}


__all__ = [
    "LIBRARY_NAME",
    "Library",
    "LibraryBlock",
    "available_libraries",
    "imported_blocks",
    "mission_folder",
]
