"""Design script: hinf-robust-corr.

Runs the 'hinf-robust-corr' design on the default family, validates it on a seeded sample,
writes its artifact (JSON + .mat) and prints the validation summary as JSON.
Equivalent to `bdft design hinf-robust-corr --json`.

    python designs/hinf_robust_corr.py [--samples N] [--seed S] [--out DIR]
"""

import sys

from robust.cli import main

if __name__ == "__main__":
    sys.exit(main(["design", "hinf-robust-corr", "--json", *sys.argv[1:]]))
