"""A plugin registry from discover_plugins looks the entry points up on first use, once."""

from __future__ import annotations

import threading

from eamos.program.camera import GIMBAL, TAKE_PHOTO
from eamos.program.plugins import ActionPlugin, PluginRegistry, discover_plugins


class Finder:
    """Counts lookups; the first caller is held until ``release`` (threads pile up on it)."""

    def __init__(self) -> None:
        self.calls = 0
        self.entered = threading.Event()
        self.release = threading.Event()

    def __call__(self) -> tuple[list[ActionPlugin], list[str]]:
        self.calls += 1
        self.entered.set()
        assert self.release.wait(30.0)
        return [TAKE_PHOTO, GIMBAL], ["entry point 'Broken' (lab:X): does not load"]


def test_nothing_is_looked_up_until_first_use_then_once() -> None:
    finder = Finder()
    told: list[str] = []
    registry = PluginRegistry(find=finder, on_problem=told.append)
    assert finder.calls == 0
    finder.release.set()
    assert registry.get("TakePhoto") is TAKE_PHOTO
    assert sorted(registry.specs()) == ["Gimbal", "TakePhoto"]
    assert registry.problems == ("entry point 'Broken' (lab:X): does not load",)
    assert finder.calls == 1
    assert told == list(registry.problems)


def test_threads_using_it_at_once_share_one_lookup() -> None:
    finder = Finder()
    registry = PluginRegistry(find=finder)
    seen: list[list[str]] = []
    threads = [
        threading.Thread(target=lambda: seen.append(sorted(registry.plugins))) for _ in range(4)
    ]
    for thread in threads:
        thread.start()
    assert finder.entered.wait(30.0)
    finder.release.set()
    for thread in threads:
        thread.join(30.0)
    assert finder.calls == 1
    assert seen == [["Gimbal", "TakePhoto"]] * 4


def test_the_installed_registry_finds_the_projects_own_camera_actions() -> None:
    registry = discover_plugins()
    assert {"TakePhoto", "Gimbal"} <= set(registry.plugins)
