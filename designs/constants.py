"""Named choices and defaults of the designs that need no numerical library.

The command line builds its options from these (choices, defaults, help texts) before it
imports any numerical module, so that ``bdft --help`` answers without NumPy. Each is
defined here once and re-exported by the module it belongs to: the actuator and sensor
sets of the achievable-limit map and its defaults by :mod:`designs.limit`,
:data:`CELLS_PER_AXIS` by :mod:`designs.scheduled`.

This module imports nothing.
"""

__all__ = [
    "ACTUATOR_SETS",
    "SENSOR_SETS",
    "ALL_SETS",
    "DEFAULT_SETS",
    "FORCE_SCALES",
    "LIMIT_SAMPLES",
    "CELLS_PER_AXIS",
]

#: Actuator sets of the limit map: name -> the loop's actuator signals.
ACTUATOR_SETS = {
    "force": ("f",),
    "reference": ("r_corr",),
    "force+reference": ("f", "r_corr"),
}
#: Sensor sets of the limit map: name -> the measured signals (``None``: every state,
#: noiseless).
SENSOR_SETS = {
    "full": None,
    "handle": ("x",),
    "handle+cab": ("x", "c"),
}
#: Every set the limit map knows: ``"actuators/sensors"``.
ALL_SETS = tuple(f"{a}/{s}" for s in SENSOR_SETS for a in ACTUATOR_SETS)
#: The limit map's default sets: every actuator set with full information, and handle force
#: and reference shaping with the handle's encoder and with the cab accelerometer added (the
#: combined actuators under output feedback are left to ``sets``: with full information
#: the reference alone already covers what they cover).
DEFAULT_SETS = (
    "force/full",
    "reference/full",
    "force+reference/full",
    "force/handle",
    "reference/handle",
    "force/handle+cab",
    "reference/handle+cab",
)
#: Force multiples of the limit map (the Omni's limits times 1, 2, 4).
FORCE_SCALES = (1.0, 2.0, 4.0)
#: Default members of the limit map's Latin hypercube (each takes about 4 core-seconds for
#: the default sets: the exact re-checks, the cutting planes and the effort constraints).
LIMIT_SAMPLES = 128
#: Default cells per identified quantity of the per-operator scheduled bank.
CELLS_PER_AXIS = 5
