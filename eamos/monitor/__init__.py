"""The live browser monitor (``eamos run --monitor``, ``eamos monitor RUN_DIR``).

* :class:`MissionSetup`, :func:`load_setup` (``setup.py``): the mission's participants,
  colours, homes and MDG pictures, read from a run folder.
* :class:`MonitorState` (``state.py``): the page's state from the ground station's events,
  pure (the one word for how a run ended is :attr:`RunSummary.word`).
* :class:`LinkCounts` (``links.py``): the triggers sent and received per link
  (drone A -> drone B), derived live from node states and the MDG's arcs, pure.
* :class:`Hub` (``hub.py``): the state behind a lock and a bounded log of patches.
* :class:`~.server.MonitorServer` (``server.py``): Starlette on uvicorn in its own thread,
  the page (``static/``), a websocket of patches, the abort endpoint.
* :class:`~.display.TeeDisplay`, :func:`~.display.start_live_monitor` (``display.py``):
  the monitor as a display of the ground station's run loop.
* :func:`~.replay.load_replay`, :func:`~.replay.serve_replay` (``replay.py``): a finished
  run folder's logs on the same page, with a time slider.

See docs/monitor.md.
"""

from __future__ import annotations

from eamos.ground.links import LinkCount, LinkCounts, LinkGraph

from .hub import Hub
from .setup import MissionSetup, MonitorError, load_setup
from .state import MonitorState

__all__ = [
    "Hub",
    "LinkCount",
    "LinkCounts",
    "LinkGraph",
    "MissionSetup",
    "MonitorError",
    "MonitorState",
    "load_setup",
]
