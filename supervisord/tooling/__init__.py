"""Tooling of the programs that run other programs: ``srcsctl demo``, the simulator's process
runner (``supervisord.sim.process``), the test kit and the benches. ``children`` starts, waits
for and ends child processes; ``polling`` waits until something holds.

The daemon never needs it: no module of ``srcsd``'s own packages imports it
(``tests/test_layers.py``).
"""
