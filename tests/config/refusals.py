"""One check for a refused fleet file: the error starts with the file and the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.config import ConfigError, FleetConfig


def assert_fleet_refused(tmp_path: Path, text: str, field: str, words: str) -> None:
    """A fleet file holding ``text`` is refused naming ``path: field`` and saying ``words``."""
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        FleetConfig.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {field}"), message
    assert words in message, message
