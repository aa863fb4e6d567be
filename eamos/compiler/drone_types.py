"""The drone types and actions a mission may use: the uniform API's plus its own.

A mission or library declares drone types as Go interfaces::

    type Inspector interface { Quadcopter; TakePhoto(); Gimbal(pitch_deg float64) }

A declared type offers the actions and properties of every type it embeds
plus the actions it lists (numbers only, with unit-named parameters).  A type
*satisfies* another if it offers all of its actions and properties (Go's
structural rule): a block parameter ``d Flyer`` accepts any drone whose type
has every action of ``Flyer``.

An action that is not the uniform API's runs only if an installed action plugin
provides it (entry points ``eamos.actions``, :mod:`eamos.program.plugins`): a declared
action with the name of a plugin must have the plugin's parameters (a located error
otherwise), and calling a declared action no plugin provides is an error (in
:mod:`eamos.compiler.check`).  The compiler reads the plugins' declarations only; it
never imports an adapter.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

from ..program.plugins import EMPTY_PLUGINS, PluginRegistry, discover_plugins
from ..program.uniform import ACTIONS, DRONE_TYPES, ActionSpec, DroneType
from .errors import Diagnostic, SourceLocation, did_you_mean
from .limits import MAX_DRONE_TYPES
from .syntax import NUMBER_TYPES, Mission, TypeDecl


@functools.cache
def installed_plugins() -> PluginRegistry:
    """The action plugins installed in this Python environment, read once per process.

    Like importlib's own path cache: a plugin installed while a long-running
    process (the language server) runs is seen after its restart.  Callers that
    hold a registry pass it instead (:func:`vocabulary`).
    """
    return discover_plugins()


def implemented_actions(vocab: Vocabulary | None = None) -> frozenset[str]:
    """The actions some adapter runs: the uniform API's and the plugins' (``vocab``'s).

    A declared action outside this set compiles in a type but is refused where
    a mission calls it (no drone could run it).
    """
    plugins = vocab.plugins if vocab is not None else installed_plugins()
    return frozenset(ACTIONS) | frozenset(plugins.plugins)


def plugin_argument_problem(vocab: Vocabulary, action: str, param: str, value: float) -> str:
    """What is wrong with one literal argument of a plugin action ("" if nothing).

    Checks the plugin's own ``ranges`` (inclusive); uniform actions are checked
    elsewhere (:func:`eamos.compiler.check.argument_problem`).
    """
    plugin = vocab.plugins.get(action)
    bounds = plugin.ranges.get(param) if plugin is not None else None
    if bounds is None or bounds[0] <= value <= bounds[1]:
        return ""
    return f"{action}'s {param} must be within {bounds[0]:g}..{bounds[1]:g}, got {value:g}"


@dataclass(frozen=True)
class Vocabulary:
    """Every drone type and action a mission may name, by name; the plugins it was checked with."""

    types: dict[str, DroneType] = field(default_factory=lambda: dict(DRONE_TYPES))
    actions: dict[str, ActionSpec] = field(default_factory=lambda: dict(ACTIONS))
    plugins: PluginRegistry = EMPTY_PLUGINS

    def missing(self, have: DroneType, want: DroneType) -> list[str]:
        """What ``have`` lacks to satisfy ``want``: its missing actions and properties."""
        return sorted(want.actions - have.actions) + [
            f"{p}()" for p in sorted(want.properties - have.properties)
        ]


class _Resolver:
    def __init__(self, mission: Mission, plugins: PluginRegistry) -> None:
        self.decls = mission.types
        self.diags: list[Diagnostic] = []
        self.vocab = Vocabulary(plugins=plugins)
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
            plugin = self.vocab.plugins.get(method.name)
            if known is None and plugin is not None:
                self.vocab.actions[method.name] = plugin.spec
                if plugin.params != params:
                    self.plugin_mismatch(method.name, plugin.params, method.loc)
            elif known is None:
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
        if decl.name in DRONE_TYPES or decl.name in NUMBER_TYPES:
            self.diags.append(
                Diagnostic(
                    "error",
                    decl.loc,
                    f"'{decl.name}' is a built-in type",
                    "give your drone type another name",
                )
            )

    def plugin_mismatch(self, name: str, params: tuple[str, ...], loc: SourceLocation) -> None:
        """A declared action whose parameters are not those of the plugin providing it."""
        sig = ", ".join(f"{p} float64" for p in params)
        self.diags.append(
            Diagnostic(
                "error",
                loc,
                f"action '{name}' is provided by an installed plugin as {name}({sig}); "
                "the declaration must match it",
                f"declare it as {name}({sig})",
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


def vocabulary(
    mission: Mission, plugins: PluginRegistry | None = None
) -> tuple[Vocabulary, list[Diagnostic]]:
    """The mission's drone types and actions, and the errors in its type declarations.

    ``plugins``: the action plugins to check declared actions against (default:
    the installed ones, :func:`installed_plugins`).
    """
    if not mission.types:
        return Vocabulary(), []
    return _Resolver(mission, installed_plugins() if plugins is None else plugins).run()
