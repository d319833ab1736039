"""Design script: workspace.

Runs the 'workspace' design on the default family, validates it on a seeded sample,
writes its artifact (JSON + .mat) and prints the validation summary as JSON.
Equivalent to `bdft design workspace --json`.

    python designs/workspace.py [--samples N] [--seed S] [--out DIR]
"""

import sys

from robust.cli import main

if __name__ == "__main__":
    sys.exit(main(["design", "workspace", "--json", *sys.argv[1:]]))
