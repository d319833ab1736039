"""Design script: cancellation.

Runs the 'cancellation' design on the default family, validates it on a seeded sample,
writes its artifact (JSON + .mat) and prints the validation summary as JSON.
Equivalent to `bdft design cancellation --json`.

    python designs/cancellation.py [--samples N] [--seed S] [--out DIR]
"""

import sys

from robust.cli import main

if __name__ == "__main__":
    sys.exit(main(["design", "cancellation", "--json", *sys.argv[1:]]))
