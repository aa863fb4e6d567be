"""Mission libraries: ``import "name"`` resolved to a folder of ``.go`` files.

A library is a folder whose ``.go`` files all declare ``package <name>``
(the folder's last name).  ``import "inspection"`` looks for the folder
``inspection`` relative to the mission's folder, then in each folder of the
``EAMOS_PATH`` environment variable (``:``-separated, like ``PATH``), then in
the standard library shipped with eamos (``eamos/missions_lib/``).

The library's blocks and drone types join the mission under the name
``package.Name``; its blocks are called as ``inspection.SEQ_Orbit(D1, 5)``.
A library may import other libraries; an import cycle, two libraries with one
package name, a package named like a drone, and a missing library are located
errors, in the file where they occur.  Every library file read is recorded
with the SHA-256 of its bytes (:class:`~.syntax.LibraryFile`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from .errors import Diagnostic, MissionError, SourceLocation
from .limits import MAX_LIBRARIES, MAX_LIBRARY_FILES
from .parse import parse_partial
from .syntax import Block, Import, LibraryFile, Mission, TypeDecl

#: The standard library's folder (package data of eamos).
STANDARD_LIBRARY = Path(__file__).resolve().parents[1] / "missions_lib"

_IMPORT_PATH = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


def search_path(mission_dir: Path | None, environ: Mapping[str, str] | None = None) -> list[Path]:
    """The folders an import is looked up in, in order."""
    env = os.environ if environ is None else environ
    out = [mission_dir] if mission_dir is not None else []
    out += [Path(p) for p in env.get("EAMOS_PATH", "").split(os.pathsep) if p]
    return [*out, STANDARD_LIBRARY]


@dataclass
class Loaded:
    """A mission with its libraries merged in, the problems found, and the files' text."""

    mission: Mission
    diagnostics: list[Diagnostic] = field(default_factory=list)
    texts: dict[str, str] = field(default_factory=dict)


class _Loader:
    def __init__(self, mission: Mission, folders: list[Path]) -> None:
        self.mission = mission
        self.folders = folders
        self.blocks: dict[str, Block] = dict(mission.blocks)
        self.types: dict[str, TypeDecl] = dict(mission.types)
        self.packages: dict[str, Path] = {}
        self.files: list[LibraryFile] = []
        self.out = Loaded(mission)

    def error(self, loc: SourceLocation, message: str, hint: str = "") -> None:
        self.out.diagnostics.append(Diagnostic("error", loc, message, hint))

    def find(self, path: str) -> Path | None:
        for base in self.folders:
            folder = base / path
            if folder.is_dir() and any(folder.glob("*.go")):
                return folder
        return None

    def load(self, imp: Import, chain: tuple[str, ...]) -> None:
        """Load one imported library and, depth first, the libraries it imports.

        The depth is bounded by :data:`MAX_LIBRARIES` (each level is a new package).
        """
        if not _IMPORT_PATH.fullmatch(imp.path):
            self.error(
                imp.loc,
                f"'{imp.path}' is not a library name",
                'a library is a folder name (letters, digits, _), e.g. import "inspection"',
            )
            return
        package = imp.path.rsplit("/", 1)[-1]
        if package in chain:
            cycle = " -> ".join([*chain[chain.index(package) :], package])
            self.error(imp.loc, f"import cycle: {cycle}", "a library cannot import itself back")
            return
        if package in self.mission.drones:
            self.error(
                imp.loc,
                f"library '{package}' has the name of drone {package}",
                "rename the drone: library.Block() and Drone.Action() would look alike",
            )
            return
        folder = self.find(imp.path)
        if folder is None:
            looked = ", ".join(str(f) for f in self.folders)
            self.error(imp.loc, f"no library '{imp.path}'", f"looked for the folder in: {looked}")
            return
        known = self.packages.get(package)
        if known is not None:
            if known.resolve() != folder.resolve():
                self.error(
                    imp.loc,
                    f"two libraries are named '{package}': {known} and {folder}",
                    "rename one of the folders",
                )
            return
        if len(self.packages) >= MAX_LIBRARIES:
            self.error(imp.loc, f"more than {MAX_LIBRARIES} libraries are imported")
            return
        self.packages[package] = folder
        files = sorted(folder.glob("*.go"))
        if len(files) > MAX_LIBRARY_FILES:
            self.error(imp.loc, f"library '{package}' has more than {MAX_LIBRARY_FILES} files")
            return
        for path in files:
            self.file(path, package, imp, chain)

    def file(self, path: Path, package: str, imp: Import, chain: tuple[str, ...]) -> None:
        try:
            data = path.read_bytes()
            text = data.decode("utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            self.error(imp.loc, f"cannot read library file {path}: {exc}")
            return
        name = str(path)
        self.out.texts[name] = text
        self.files.append(LibraryFile(name, package, hashlib.sha256(data).hexdigest()))
        try:
            lib, diags, fatal = parse_partial(text, file=name, package=package)
        except MissionError as exc:  # empty, not text, too large: nothing to read
            self.out.diagnostics.extend(exc.diagnostics)
            return
        self.out.diagnostics.extend(diags)
        if fatal:
            return
        if lib.name != package:
            self.error(
                SourceLocation(1, 1, name),
                f"this library file declares package '{lib.name}', but its folder is '{package}'"
                if lib.name != "mission"
                else "a library file starts with its package",
                f"write: package {package}",
            )
            return
        for block in lib.blocks.values():
            first = self.blocks.get(block.name)
            if first is not None:
                self.error(
                    block.loc,
                    f"block '{block.name}' is defined twice",
                    f"first defined at {first.loc.file or 'the mission'}:{first.loc.line}",
                )
                continue
            self.blocks[block.name] = block
        for decl in lib.types.values():
            if decl.name in self.types:
                self.error(decl.loc, f"drone type '{decl.name}' is declared twice")
                continue
            self.types[decl.name] = decl
        for sub in lib.imports:
            self.load(sub, (*chain, package))


def load_libraries(
    mission: Mission, mission_dir: Path | None, environ: Mapping[str, str] | None = None
) -> Loaded:
    """The mission with every library it imports merged in (see the module's doc)."""
    if not mission.imports:
        return Loaded(mission)
    loader = _Loader(mission, search_path(mission_dir, environ))
    for imp in mission.imports:
        loader.load(imp, ())
    loader.out.mission = dataclasses.replace(
        mission, blocks=loader.blocks, types=loader.types, libraries=tuple(loader.files)
    )
    return loader.out
