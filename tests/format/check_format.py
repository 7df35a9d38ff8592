#!/usr/bin/env python3
"""Checks that every C++ source of the tree is clang-format clean under the repository's .clang-format.

Usage: check_format.py SOURCE_DIR [--clang-format PATH] [--fix]

The files are the tracked ones when SOURCE_DIR is a git checkout (so build trees and scratch files do not
count), else every *.h / *.cpp below the source folders. With --fix the files are rewritten in place
(what a contributor runs before committing); without it the check lists every file that would change
and exits 1.
"""
import argparse
import os
import shutil
import subprocess
import sys

FOLDERS = ("engine", "storage", "problems", "cvodes", "petsc", "cli", "python", "bench", "examples", "tests")


def sources(root):
    try:
        listed = subprocess.run(["git", "-C", root, "ls-files", "-z", "--", "*.h", "*.cpp"], check=True,
                                capture_output=True).stdout.decode().split("\0")
        return sorted(os.path.join(root, f) for f in listed if f and os.path.isfile(os.path.join(root, f)))
    except (OSError, subprocess.CalledProcessError):
        found = []
        for folder in FOLDERS:
            for base, _, names in os.walk(os.path.join(root, folder)):
                found += [os.path.join(base, n) for n in names if n.endswith((".h", ".cpp"))]
        return sorted(found)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("root")
    parser.add_argument("--clang-format", default=shutil.which("clang-format") or shutil.which("clang-format-14"))
    parser.add_argument("--fix", action="store_true")
    args = parser.parse_args()
    if not args.clang_format or not shutil.which(args.clang_format):
        print(f"check_format: clang-format not found ({args.clang_format}; Debian package clang-format)",
              file=sys.stderr)
        return 2
    files = sources(args.root)
    if not files:
        print(f"check_format: no C++ sources below {args.root}", file=sys.stderr)
        return 2
    if args.fix:
        subprocess.run([args.clang_format, "-i", "--style=file"] + files, check=True)
        print(f"check_format: formatted {len(files)} files")
        return 0
    unclean = []
    for f in files:
        r = subprocess.run([args.clang_format, "--dry-run", "-Werror", "--style=file", f], capture_output=True)
        if r.returncode != 0:
            unclean.append(os.path.relpath(f, args.root))
    for f in unclean:
        print(f"not clang-format clean: {f}")
    print(f"check_format: {len(files) - len(unclean)} of {len(files)} files clean")
    if unclean:
        print("fix with: /usr/bin/python3 tests/format/check_format.py . --fix")
    return 1 if unclean else 0


if __name__ == "__main__":
    sys.exit(main())
