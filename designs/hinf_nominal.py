"""Design script: hinf-nominal.

Runs the 'hinf-nominal' design on the default family, validates it on a seeded sample,
writes its artifact (JSON + .mat) and prints the validation summary as JSON.
Equivalent to `bdft design hinf-nominal --json`.

    python designs/hinf_nominal.py [--samples N] [--seed S] [--out DIR]
"""

import sys

from robust.cli import main

if __name__ == "__main__":
    sys.exit(main(["design", "hinf-nominal", "--json", *sys.argv[1:]]))
