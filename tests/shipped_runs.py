"""The shipped designs run end to end on the margins tests' sample: 500 Latin-hypercube
members of the default family, seed 0, no coverage check; each design once per test module
(the module's ``runs`` dict keeps them)."""

from designs.registry import run_design

SAMPLES, SEED = 500, 0


def shipped_run(runs: dict, name: str):
    """The design ``name`` (:func:`designs.registry.run_design`), run once per ``runs``."""
    if name not in runs:
        runs[name] = run_design(name, samples=SAMPLES, seed=SEED, coverage_samples=0)
    return runs[name]
