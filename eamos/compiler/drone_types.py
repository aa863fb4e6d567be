"""The drone types and actions a mission may use: the uniform API's plus its own.

A mission or library declares drone types as Go interfaces::

    type Inspector interface { Quadcopter; TakePhoto(); Gimbal(pitch_deg float64) }

A declared type offers the actions and properties of every type it embeds
plus the actions it lists (numbers only, with unit-named parameters).  A type
*satisfies* another if it offers all of its actions and properties (Go's
structural rule): a block parameter ``d Flyer`` accepts any drone whose type
has every action of ``Flyer``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..program.uniform import ACTIONS, DRONE_TYPES, ActionSpec, DroneType
from .errors import Diagnostic, did_you_mean
from .limits import MAX_DRONE_TYPES
from .syntax import Mission, TypeDecl

#: The parameter type of numbers.
NUMBER = "float64"


def implemented_actions() -> frozenset[str]:
    """The actions some adapter runs today: the uniform API's.

    A declared action outside this set compiles in a type but is refused where
    a mission calls it (no drone could run it yet).
    """
    return frozenset(ACTIONS)


@dataclass(frozen=True)
class Vocabulary:
    """Every drone type and action a mission may name, by name."""

    types: dict[str, DroneType] = field(default_factory=lambda: dict(DRONE_TYPES))
    actions: dict[str, ActionSpec] = field(default_factory=lambda: dict(ACTIONS))

    def missing(self, have: DroneType, want: DroneType) -> list[str]:
        """What ``have`` lacks to satisfy ``want``: its missing actions and properties."""
        return sorted(want.actions - have.actions) + [
            f"{p}()" for p in sorted(want.properties - have.properties)
        ]


class _Resolver:
    def __init__(self, mission: Mission) -> None:
        self.decls = mission.types
        self.diags: list[Diagnostic] = []
        self.vocab = Vocabulary()
        self.state: dict[str, int] = {}  # 1 = being resolved, 2 = done

    def run(self) -> tuple[Vocabulary, list[Diagnostic]]:
        if len(self.decls) > MAX_DRONE_TYPES:
            decl = list(self.decls.values())[MAX_DRONE_TYPES]
            self.diags.append(
                Diagnostic(
                    "error",
                    decl.loc,
                    f"more than {MAX_DRONE_TYPES} drone types are declared",
                    "declare fewer types; embed one in another to share actions",
                )
            )
            return self.vocab, self.diags
        for decl in self.decls.values():
            self.actions_of(decl)
        for decl in self.decls.values():
            self.resolve(decl.name)
        return self.vocab, self.diags

    def actions_of(self, decl: TypeDecl) -> None:
        for method in decl.methods:
            params = tuple(p.name for p in method.params)
            known = self.vocab.actions.get(method.name)
            if known is None:
                self.vocab.actions[method.name] = ActionSpec(
                    method.name, params, f"Declared by drone type {decl.name}.", payload=True
                )
            elif len(known.params) != len(params):
                sig = ", ".join(f"{p} float64" for p in known.params)
                where = "the uniform API" if method.name in ACTIONS else "another drone type"
                self.diags.append(
                    Diagnostic(
                        "error",
                        method.loc,
                        f"action '{method.name}' is declared by {where} with "
                        f"{len(known.params)} parameter{'s' if len(known.params) != 1 else ''}",
                        f"declare it as {method.name}({sig})",
                    )
                )
        if decl.name in DRONE_TYPES or decl.name == NUMBER:
            self.diags.append(
                Diagnostic(
                    "error",
                    decl.loc,
                    f"'{decl.name}' is a built-in type",
                    "give your drone type another name",
                )
            )

    def resolve(self, name: str) -> DroneType | None:
        """The declared type ``name`` with its embedded types resolved (None on error).

        Recursion is bounded by :data:`MAX_DRONE_TYPES` (each level is a new type).
        """
        if name in self.vocab.types and self.state.get(name) != 1:
            return self.vocab.types[name]
        decl = self.decls.get(name)
        if decl is None or self.state.get(name) == 1:
            return None
        self.state[name] = 1
        actions = {m.name for m in decl.methods}
        properties: set[str] = set()
        for embed, loc in decl.embeds:
            if embed in DRONE_TYPES:
                inner: DroneType | None = DRONE_TYPES[embed]
            elif self.state.get(embed) == 1:
                self.diags.append(
                    Diagnostic(
                        "error",
                        loc,
                        f"drone types embed each other in a cycle ('{name}' embeds '{embed}')",
                        "a type embeds only types that do not embed it",
                    )
                )
                continue
            elif embed not in self.decls:
                self.diags.append(
                    Diagnostic(
                        "error",
                        loc,
                        f"unknown drone type '{embed}'",
                        did_you_mean(embed, [*DRONE_TYPES, *self.decls]),
                    )
                )
                continue
            else:
                inner = self.resolve(embed)
            if inner is not None:
                actions |= inner.actions
                properties |= inner.properties
        self.state[name] = 2
        dtype = DroneType(name, frozenset(actions), frozenset(properties), "declared")
        self.vocab.types[name] = dtype
        return dtype


def vocabulary(mission: Mission) -> tuple[Vocabulary, list[Diagnostic]]:
    """The mission's drone types and actions, and the errors in its type declarations."""
    if not mission.types:
        return Vocabulary(), []
    return _Resolver(mission).run()
