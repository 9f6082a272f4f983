"""Experiments built on runs: the thesis's offline displacement experiment (:mod:`.offline`, its robots
:mod:`.offline_bench`), parameter sweeps (:mod:`.plan` → :mod:`.sweep` → :mod:`.store`, :mod:`.tables`,
:mod:`.plots`), the window report (:mod:`.window_report`) and their subcommands (:mod:`.cli`:
``circsim offline``, ``circsim sweep``). See docs/experiments.md and docs/sweeps.md.
"""
