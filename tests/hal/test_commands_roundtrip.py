"""Every uniform action decodes into a typed command that gives back its name and arguments."""

from __future__ import annotations

import pytest

from eamos.program.uniform import ACTIONS, Command, decode_command


@pytest.mark.parametrize("name", sorted(ACTIONS))
def test_a_decoded_command_gives_back_its_action_and_arguments(name: str) -> None:
    args = tuple(float(i + 2) for i in range(len(ACTIONS[name].params)))
    command = decode_command(name, args)
    assert isinstance(command, Command)
    assert (command.action, command.args) == (name, args)
    assert decode_command(command.action, command.args) == command
