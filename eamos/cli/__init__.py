"""Command-line code: every console entry point, one exit-code table, shared option builders.

What others may use (nothing below the CLI imports it; tests/test_layering.py):

* :mod:`eamos.cli.main`    -- ``eamos`` (:func:`~eamos.cli.main.main`, ``build_parser``);
* :mod:`eamos.cli.exits`   -- the exit-code table (0 ok, 1 mission failed, 2 bad input,
  3 could not connect, 4 internal error);
* :mod:`eamos.cli.errors`  -- the one place an exception becomes an exit code and one
  line, for every entry point (:data:`~eamos.cli.errors.EXIT_CODE_OF`,
  :func:`~eamos.cli.errors.run_reported`, ``eamos``'s :func:`~eamos.cli.errors.dispatch`),
  and :class:`~eamos.cli.errors.BadInput`;
* :mod:`eamos.cli.options` -- option builders shared by the commands
  (``--run-dir``, ``--speedup``, ``--svg/--no-svg``, ``-v``, timeouts in seconds).

The commands: :mod:`.compile` (compile, graph), :mod:`.run`, :mod:`.fleet` (rollout,
start, status, abort, logs fetch), :mod:`.report`, :mod:`.keys`; the other entry
points: :mod:`.node` (``eamos-node``), :mod:`.sim_vehicle` (``eamos-sim-vehicle``).
"""

# The entry points are modules (above); the package itself exports nothing.
__all__: list[str] = []
