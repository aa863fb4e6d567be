"""The standard library of missions: folders of ``.go`` files a mission imports.

``import "fleet"``, ``import "shapes"``, ``import "survey"`` find these folders
after the mission's own folder and ``EAMOS_PATH`` (see
:mod:`eamos.compiler.libraries` and docs/mission-language.md).  No Python here:
the folders are package data.
"""

__all__: list[str] = []
