"""Tasks that test_engine sends to other processes (loky's workers, a Dask cluster's).

A worker unpickles a task by importing the module that defines it: here only numpy, not the
test module with the whole package behind it (each worker process spent seconds of CPU
importing that before it could run a task of a few microseconds).
"""

import os

import numpy as np


def power(k, x):
    return float(np.sum(np.linspace(0.0, 1.0, 7) ** k) * x)


def pid(_):
    return os.getpid()
