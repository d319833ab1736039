"""Design script: virtual-damping.

Runs the 'virtual-damping' design on the default family, validates it on a seeded sample,
writes its artifact (JSON + .mat) and prints the validation summary as JSON.
Equivalent to `bdft design virtual-damping --json`.

    python designs/virtual_damping.py [--samples N] [--seed S] [--out DIR]
"""

import sys

from robust.cli import main

if __name__ == "__main__":
    sys.exit(main(["design", "virtual-damping", "--json", *sys.argv[1:]]))
