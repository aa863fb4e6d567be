"""Action plugins: actions a lab adds without editing the project (entry points ``eamos.actions``).

A plugin is pure data, an :class:`ActionPlugin`: the action's name, its parameters (numbers,
named with their unit like the uniform API's: ``pitch_deg``, ``duration_s``) and, per adapter
family, where its implementation lives (``"module:callable"``, imported only by the adapter
that runs it).  A package installs one with an entry point in the group ``eamos.actions``::

    [project.entry-points."eamos.actions"]
    Spray = "mylab.eamos_spray:SPRAY"     # SPRAY is an ActionPlugin named "Spray"

The module holding the :class:`ActionPlugin` must be light (it may import only
``eamos.program``): the compiler loads it to check missions.  Discovery returns a
:class:`PluginRegistry` object that callers pass on; nothing global is mutated.

Adapter families: ``"sim"`` (the simulated quadcopter, the virtual driver's vehicles, the fake
adapter) and ``"mavlink"`` (PX4 and ArduPilot).  The ground station runs no plugin action.
See docs/plugins.md.

A plugin is code EAMOS does not control, so :meth:`PluginRegistry.call` runs an
implementation on a thread of its own under a deadline (:class:`PluginCall`): whatever it
raises (``SystemExit`` and ``KeyboardInterrupt`` included) or however long it takes, the
caller gets an answer, never the exception and never a wait past the deadline.
"""

from __future__ import annotations

import importlib
import re
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from .uniform import ACTIONS, ActionSpec

#: The entry-point group plugins are installed under.
ENTRY_POINT_GROUP = "eamos.actions"

#: The adapter families a plugin may implement an action for.
FAMILIES = ("sim", "mavlink")

_NAME = re.compile(r"[A-Z][A-Za-z0-9]*\Z")
_PARAM = re.compile(r"[a-z][a-z0-9]*(_[a-z0-9]+)*_(m|deg|s|m_s|pct|count)\Z")


#: How long one call of a plugin implementation may take by default (wall-clock seconds).
#: A "sim" implementation computes an outcome (microseconds); the bound leaves room for
#: its module's first import on a loaded machine.
PLUGIN_DEADLINE_S = 10.0


class PluginError(Exception):
    """A plugin that cannot be used: a bad declaration or an implementation that does not load."""


@dataclass(frozen=True)
class PluginAnswer:
    """What one call of a plugin implementation gave: its ``value``, or why it ``failed``."""

    value: Any = None
    failed: str = ""  # a sentence naming the plugin action; "" when it returned


class PluginCall:
    """One call of a plugin implementation, on a daemon thread of its own, under a deadline.

    Made by :meth:`PluginRegistry.call`.  :meth:`poll` never waits; :meth:`wait` waits
    at most until the deadline.  Past the deadline the call has *failed* ("did not finish
    within N s") and its thread is abandoned: Python cannot stop a thread, so a plugin
    that sleeps or spins forever keeps its thread (a daemon: it never holds up the
    process's exit) and its later result is dropped.  Anything the implementation raises,
    ``BaseException`` included, is its failure: the thread is never the process's main
    thread, so a ``KeyboardInterrupt`` there was raised by the plugin, not by Ctrl-C.
    """

    def __init__(
        self,
        registry: PluginRegistry,
        name: str,
        family: str,
        args: tuple[Any, ...],
        deadline_s: float,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.name = name
        self.family = family
        self.deadline_s = deadline_s
        self._registry = registry
        self._clock = clock
        self._due = clock() + deadline_s
        self._lock = threading.Lock()  # the implementation's thread and the deadline race
        self._done = threading.Event()
        self._answer: PluginAnswer | None = None
        earlier = registry.overran(name, family)
        if earlier is not None:  # its thread may still run: never a second one
            self._settle(
                PluginAnswer(
                    failed=f"plugin action {name!r} did not finish within {earlier:g} s "
                    "before: not called again"
                )
            )
            return
        threading.Thread(
            target=self._call, args=args, name=f"plugin-{name}-{family}", daemon=True
        ).start()

    def _call(self, *args: Any) -> None:
        try:
            implementation = self._registry.implementation(self.name, self.family)
            answer = PluginAnswer(value=implementation(*args))
        except PluginError as exc:
            answer = PluginAnswer(failed=str(exc))
        except BaseException as exc:  # its own thread: whatever it raised is its failure
            answer = PluginAnswer(
                failed=f"plugin action {self.name!r} failed in its {self.family} "
                f"implementation: {exc!r}"
            )
        self._settle(answer)

    def _settle(self, answer: PluginAnswer) -> None:
        with self._lock:
            if self._answer is None:
                self._answer = answer
                self._done.set()

    def poll(self) -> PluginAnswer | None:
        """The answer, or None while the implementation runs and its deadline is ahead."""
        if not self._done.is_set() and self._clock() >= self._due:
            self._overran()
        return self._answer

    def wait(self) -> PluginAnswer:
        """The answer, waiting for it at most until the deadline."""
        if not self._done.wait(max(0.0, self._due - self._clock())):
            self._overran()
        answer = self._answer
        assert answer is not None
        return answer

    def _overran(self) -> None:
        failed = f"plugin action {self.name!r} did not finish within {self.deadline_s:g} s"
        with self._lock:
            if self._answer is not None:
                return  # it finished just in time
            self._answer = PluginAnswer(failed=failed)
            self._done.set()
        self._registry.mark_overran(self.name, self.family, self.deadline_s)


@dataclass(frozen=True)
class ActionPlugin:
    """One plugin action: name, unit-named number parameters, implementation per family.

    ``implementations`` maps a family (:data:`FAMILIES`) to ``"module:callable"``;
    ``ranges`` optionally bounds parameters (inclusive), for the compiler's checks
    (:func:`eamos.compiler.drone_types.plugin_argument_problem`).
    """

    name: str
    params: tuple[str, ...]
    doc: str
    implementations: Mapping[str, str] = field(default_factory=dict)
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def problems(self) -> list[str]:
        """What is wrong with this declaration (empty when it is usable)."""
        out: list[str] = []
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            out.append(f"action name {self.name!r} is not a CamelCase identifier")
        elif self.name in ACTIONS:
            out.append(f"action {self.name!r} is a uniform action; a plugin cannot replace it")
        if not isinstance(self.params, tuple):
            return [*out, "params must be a tuple of parameter names"]
        for param in self.params:
            if not isinstance(param, str) or not _PARAM.match(param):
                out.append(
                    f"parameter {param!r} must be lower_snake_case ending in its unit "
                    "(_m, _deg, _s, _m_s, _pct, _count)"
                )
        if len(set(self.params)) != len(self.params):
            out.append("parameter names repeat")
        for family, target in dict(self.implementations).items():
            if family not in FAMILIES:
                out.append(f"unknown adapter family {family!r} (known: {', '.join(FAMILIES)})")
            if not isinstance(target, str) or target.count(":") != 1:
                out.append(f"implementation for {family!r} must be 'module:callable'")
        for param, bounds in dict(self.ranges).items():
            if param not in self.params:
                out.append(f"range for unknown parameter {param!r}")
            elif len(bounds) != 2 or not bounds[0] <= bounds[1]:
                out.append(f"range of {param!r} must be (low, high) with low <= high")
        return out

    @property
    def spec(self) -> ActionSpec:
        """The action as the compiler and :func:`~eamos.program.uniform.decode_command` see it."""
        return ActionSpec(self.name, self.params, self.doc, payload=True)

    @property
    def families(self) -> tuple[str, ...]:
        """The families with an implementation, in :data:`FAMILIES` order."""
        return tuple(f for f in FAMILIES if f in self.implementations)


class PluginRegistry:
    """The plugins one process uses, by action name; passed around, never global.

    ``problems`` lists the entry points that could not be used (a broken plugin
    must not stop a mission that does not call it).  Implementations are
    imported on first use and cached in this object.

    A registry made by :func:`discover_plugins` looks the entry points up on the
    first use of :attr:`plugins` or :attr:`problems` (any method), once, and then
    tells each problem to ``on_problem``: a drone whose program calls no plugin
    action need not scan the installed distributions at start-up.
    """

    def __init__(
        self,
        plugins: Iterable[ActionPlugin] = (),
        problems: Iterable[str] = (),
        *,
        find: Callable[[], tuple[list[ActionPlugin], list[str]]] | None = None,
        on_problem: Callable[[str], None] | None = None,
    ) -> None:
        self._plugins: Mapping[str, ActionPlugin] = MappingProxyType({p.name: p for p in plugins})
        self._problems: tuple[str, ...] = tuple(problems)
        self._find = find  # None once found (or when given the plugins)
        self._on_problem = on_problem
        self._finding = threading.Lock()
        self._loaded: dict[tuple[str, str], Callable[..., Any]] = {}
        self._overran_lock = threading.Lock()
        self._overran: dict[tuple[str, str], float] = {}  # (name, family) -> deadline missed

    @property
    def plugins(self) -> Mapping[str, ActionPlugin]:
        """The usable plugins by action name."""
        self._look_up()
        return self._plugins

    @property
    def problems(self) -> tuple[str, ...]:
        """The entry points that could not be used, one sentence each."""
        self._look_up()
        return self._problems

    def _look_up(self) -> None:
        """Find the plugins, once (the first caller finds, the others wait for it)."""
        if self._find is None:
            return
        with self._finding:
            find = self._find
            if find is None:
                return
            plugins, problems = find()
            self._plugins = MappingProxyType({p.name: p for p in plugins})
            self._problems = tuple(problems)
            self._find = None  # last: a reader that sees None sees the plugins
        if self._on_problem is not None:
            for problem in self._problems:
                self._on_problem(problem)

    def __repr__(self) -> str:
        return f"PluginRegistry({sorted(self.plugins)})"

    def get(self, name: str) -> ActionPlugin | None:
        """The plugin named ``name``, or None."""
        return self.plugins.get(name)

    def specs(self) -> Mapping[str, ActionSpec]:
        """Every plugin action as an :class:`ActionSpec`, by name."""
        return {name: p.spec for name, p in self.plugins.items()}

    def implemented_by(self, family: str) -> frozenset[str]:
        """The plugin actions with an implementation for ``family``."""
        return frozenset(n for n, p in self.plugins.items() if family in p.implementations)

    def call(
        self,
        name: str,
        family: str,
        args: tuple[Any, ...],
        deadline_s: float = PLUGIN_DEADLINE_S,
    ) -> PluginCall:
        """Start ``name``'s ``family`` implementation on ``args``, on a thread of its own.

        The :class:`PluginCall` answers within ``deadline_s`` (wall-clock seconds) whatever
        the implementation does; one that missed its deadline is not called again by this
        registry (each later call fails at once: its thread may still be running).  Each
        simulated drone has a registry of its own; an ``eamos check`` has one.
        """
        return PluginCall(self, name, family, args, deadline_s)

    def overran(self, name: str, family: str) -> float | None:
        """The deadline ``name``'s ``family`` implementation missed (None: it never did)."""
        with self._overran_lock:
            return self._overran.get((name, family))

    def mark_overran(self, name: str, family: str, deadline_s: float) -> None:
        """Remember that a call of ``name``'s implementation missed ``deadline_s``."""
        with self._overran_lock:
            self._overran.setdefault((name, family), deadline_s)

    def implementation(self, name: str, family: str) -> Callable[..., Any]:
        """Import and return ``name``'s implementation for ``family`` (cached).

        Raises :class:`PluginError` with a clear message when there is none
        or it does not import.
        """
        key = (name, family)
        if key in self._loaded:
            return self._loaded[key]
        plugin = self.plugins.get(name)
        if plugin is None:
            raise PluginError(f"no plugin provides action {name!r}")
        target = plugin.implementations.get(family)
        if target is None:
            have = ", ".join(plugin.families) or "none"
            raise PluginError(
                f"plugin action {name!r} has no {family!r} implementation (it has: {have})"
            )
        module_name, _, attr = target.partition(":")
        try:
            found: Any = importlib.import_module(module_name)
            for part in attr.split("."):
                found = getattr(found, part)
        except Exception as exc:  # a broken plugin: say which, never crash the adapter
            raise PluginError(
                f"plugin action {name!r}: cannot load its {family!r} implementation "
                f"{target!r}: {exc!r}"
            ) from exc
        if not callable(found):
            raise PluginError(f"plugin action {name!r}: {target!r} is not callable")
        self._loaded[key] = found
        return found  # type: ignore[no-any-return]


#: A registry with no plugin (tests, the ground station).
EMPTY_PLUGINS = PluginRegistry()


def discover_plugins(
    group: str = ENTRY_POINT_GROUP, on_problem: Callable[[str], None] | None = None
) -> PluginRegistry:
    """The plugins installed through entry points in ``group`` (importlib.metadata).

    Loads each entry point's :class:`ActionPlugin`; an entry point that does not
    load, is not an :class:`ActionPlugin`, is named differently from its action,
    declares itself badly or repeats another's name goes to ``problems`` instead.
    The lookup happens on the registry's first use (:class:`PluginRegistry`);
    ``on_problem`` is then told each problem.
    """
    return PluginRegistry(find=lambda: _find_plugins(group), on_problem=on_problem)


def _find_plugins(group: str) -> tuple[list[ActionPlugin], list[str]]:
    """The usable plugins of the entry points in ``group``, and the problems of the others."""
    # Imported here, not at the top: importlib.metadata (with email, zipfile, csv) costs
    # eamos-node's start-up tens of ms, and only adapters that look plugins up need it.
    from importlib import metadata

    plugins: dict[str, ActionPlugin] = {}
    problems: list[str] = []
    seen: set[tuple[str, str]] = set()
    for ep in metadata.entry_points(group=group):
        if (ep.name, ep.value) in seen:
            continue  # one distribution found twice on the path
        seen.add((ep.name, ep.value))
        where = f"entry point {ep.name!r} ({ep.value})"
        try:
            plugin = ep.load()
        except Exception as exc:  # a broken plugin must not break the others
            problems.append(f"{where}: does not load: {exc!r}")
            continue
        if not isinstance(plugin, ActionPlugin):
            problems.append(f"{where}: is a {type(plugin).__name__}, not an ActionPlugin")
            continue
        if plugin.name != ep.name:
            problems.append(f"{where}: names action {plugin.name!r}; the names must be equal")
            continue
        bad = plugin.problems()
        if bad:
            problems.append(f"{where}: {'; '.join(bad)}")
            continue
        if plugin.name in plugins:
            problems.append(f"{where}: action {plugin.name!r} is provided twice")
            continue
        plugins[plugin.name] = plugin
    return list(plugins.values()), problems


__all__ = [
    "EMPTY_PLUGINS",
    "ENTRY_POINT_GROUP",
    "FAMILIES",
    "PLUGIN_DEADLINE_S",
    "ActionPlugin",
    "PluginAnswer",
    "PluginCall",
    "PluginError",
    "PluginRegistry",
    "discover_plugins",
]
