"""The ground station: the station actor, the one run loop, the run summary.

See docs/architecture.md.
"""
