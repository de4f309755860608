"""The virtualenv each comparison script of bench/ runs in (shared by those scripts).

A script calls `ensure_venv(name, packages, __file__)` first: outside `bench/<name>` it creates
that virtualenv (once), installs `packages` from PyPI, and re-executes itself inside it with the
same arguments. A marker file is written only after the install succeeds, so an interrupted or
failed install is redone on the next run instead of leaving a virtualenv without its packages.
"""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def ensure_venv(name, packages, script):
    """Run `script` inside bench/<name> with `packages` installed (see the module's doc)."""
    venv_dir = os.path.join(ROOT, "bench", name)
    python = os.path.join(venv_dir, "bin", "python")
    if os.path.realpath(sys.prefix) == os.path.realpath(venv_dir):
        return
    marker = os.path.join(venv_dir, "installed.txt")
    wanted = " ".join(packages)
    if not os.path.exists(marker) or open(marker).read().strip() != wanted:
        import venv

        print(f"creating {venv_dir} ({', '.join(packages)} from PyPI)...", flush=True)
        venv.create(venv_dir, with_pip=True)
        subprocess.check_call([python, "-m", "pip", "install", "--quiet", *packages])
        with open(marker, "w") as f:
            f.write(wanted + "\n")
    os.execv(python, [python, os.path.abspath(script)] + sys.argv[1:])
