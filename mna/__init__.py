"""Minimal Neural Atlas: fit, extract, texture and render (see DESIGN.md)."""
import os as _os

# On a shared or oversubscribed machine, OpenMP workers that spin-wait between parallel
# regions steal the cores the busy ones need: with one other process on one of two cores
# a fit ran at ~2 steps/s instead of 7-9. PASSIVE makes idle workers sleep. It must be
# set before torch (and its OpenMP runtime) is imported, so it lives in the package's
# first import; a value the user exported wins.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
