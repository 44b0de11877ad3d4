#!/usr/bin/env python3
"""Check that the installed Python packages match a requirements file.

    check-requirements.py REQUIREMENTS

Every line (name, optional specifier such as ==2.1.0.post1 or >=7) must be
installed in a version the specifier accepts; exits 1 and names each that
is missing or differs. Run it with the Python that runs the tests (the venv's
of tests/install-deps.sh).
"""
import importlib.metadata as md
import sys

try:
    from packaging.requirements import Requirement
except ImportError:  # a venv always has pip, which carries packaging
    from pip._vendor.packaging.requirements import Requirement


def check(path):
    bad = []
    for raw in open(path, encoding="utf-8"):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        req = Requirement(line)
        try:
            have = md.version(req.name)
        except md.PackageNotFoundError:
            bad.append(f"{req.name}: not installed (wanted {req.specifier or 'any'})")
            continue
        if req.specifier and not req.specifier.contains(have, prereleases=True):
            bad.append(f"{req.name}: {have} installed, {req.specifier} wanted")
    return bad


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__.strip().splitlines()[2].strip())
    bad = check(sys.argv[1])
    for b in bad:
        print(f"check-requirements: {b} ({sys.executable})", file=sys.stderr)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
