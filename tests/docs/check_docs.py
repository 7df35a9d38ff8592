#!/usr/bin/env python3
"""Checks that keep the documentation and the comments honest (ctest label docs):

  paths   every repository path cited in a comment, a doc page or the README exists;
  issues  no issue numbers (a hash and digits, or the word issue and a number) in code, comments or
          docs: text must stand on its own;
  blocks  a code block marked <!-- same-as: PATH --> in a page is exactly the file PATH (which its own
          test builds and runs), so the page cannot drift from the program;
  flags   every --flag of a `hindsight SUBCOMMAND` command line in a page's sh blocks is one that
          `hindsight SUBCOMMAND --help` lists, and every subcommand and flag the tool's --help lists is
          documented in docs/reference/cli.md (with --cli PATH): the reference is complete and current.

Usage: check_docs.py --root SOURCE_DIR [--cli build/hindsight] [--only paths,issues,blocks,flags]
Exit code 1 with every finding listed, 0 when clean.
"""
import argparse
import os
import re
import subprocess
import sys

# Text files whose content is checked, by suffix or name; data (JSON, HDF5, images) is not text to check.
TEXT_SUFFIXES = (".h", ".cpp", ".c", ".py", ".pyi", ".md", ".cmake", ".in", ".sh", ".toml", ".txt", ".supp")
TEXT_NAMES = ("CMakeLists.txt", "setup", "run", "sanitize", "Doxyfile.in")
SKIP_DIRS = {".git", "build", "__pycache__"}
# The repository's top-level folders: a cited path starts with one of them.
TOP = r"(?:engine|storage|cvodes|problems|cli|python|tests|bench|docs|examples|cmake|petsc|\.ci)"
PATH = re.compile(r"(?<![\w/.$<-])(" + TOP + r"/[A-Za-z0-9_./-]*[A-Za-z0-9_])")
ISSUE = re.compile(r"\b[Ii]ssues?\s+#?\d+\b|(?<![\w&#/])#\d{1,4}\b(?![\w-])")


def text_files(root):
    for directory, subdirectories, files in os.walk(root):
        subdirectories[:] = sorted(d for d in subdirectories
                                   if d not in SKIP_DIRS and not (directory == root and d.startswith("build")))
        for name in sorted(files):
            if name.endswith(TEXT_SUFFIXES) or name in TEXT_NAMES:
                path = os.path.join(directory, name)
                yield os.path.relpath(path, root), path


def check_paths(root, files):
    findings = []
    for relative, path in files:
        with open(path, encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, 1):
                for match in PATH.finditer(line):
                    cited = match.group(1).rstrip(".")
                    following = line[match.end():match.end() + 1]
                    if following in ("{", "*", "<", "$") or re.search(r"/[A-Z][A-Z_]+(/|$)", cited):
                        cited = os.path.dirname(cited)  # a pattern or a placeholder: its folder must exist
                        cited = re.sub(r"/[A-Z][A-Z_]+(/.*)?$", "", cited)
                    if not os.path.exists(os.path.join(root, cited)) and re.search(r"[A-Z]{3,}", cited.split("/")[-1]):
                        cited = os.path.dirname(cited)  # bench/results-MODE: a placeholder in the name
                    if not os.path.exists(os.path.join(root, cited)):
                        findings.append(f"{relative}:{number}: cites '{cited}', which does not exist")
    return findings


def check_issues(files):
    findings = []
    for relative, path in files:
        with open(path, encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, 1):
                for match in ISSUE.finditer(line):
                    findings.append(f"{relative}:{number}: issue number '{match.group(0)}': say what, not which ticket")
    return findings


FENCE = re.compile(r"^(`{3,})([\w+-]*)[^\n]*\n(.*?)^\1[ \t]*$", re.S | re.M)


def markdown_files(root):
    pages = [os.path.join(root, "README.md")]
    for directory, _, files in os.walk(os.path.join(root, "docs")):
        pages += [os.path.join(directory, name) for name in sorted(files) if name.endswith(".md")]
    return pages


def check_blocks(root):
    findings = []
    marker = re.compile(r"<!--\s*same-as:\s*(\S+)\s*-->\s*\n(`{3,})[\w+-]*\n(.*?)^\2[ \t]*$", re.S | re.M)
    for page in markdown_files(root):
        with open(page, encoding="utf-8") as f:
            text = f.read()
        for match in marker.finditer(text):
            target = os.path.join(root, match.group(1))
            relative = os.path.relpath(page, root)
            if not os.path.exists(target):
                findings.append(f"{relative}: same-as '{match.group(1)}' does not exist")
                continue
            with open(target, encoding="utf-8") as f:
                if f.read() != match.group(3):
                    findings.append(f"{relative}: the block marked same-as {match.group(1)} differs from that file")
    return findings


def check_flags(root, cli):
    findings = []
    helps = {}
    command = re.compile(r"(?:\./build/|\b)hindsight\s+([a-z]+)\b(.*)")
    for page in markdown_files(root):
        with open(page, encoding="utf-8") as f:
            text = f.read()
        for fence in FENCE.finditer(text):
            if fence.group(2) not in ("sh", "bash", "console"):
                continue
            logical = fence.group(3).replace("\\\n", " ")
            for line in logical.splitlines():
                line = line.split("#", 1)[0]
                for match in command.finditer(line):
                    subcommand, rest = match.group(1), match.group(2)
                    if subcommand not in helps:
                        result = subprocess.run([cli, subcommand, "--help"], capture_output=True, text=True)
                        helps[subcommand] = result.stdout if result.returncode == 0 else None
                    relative = os.path.relpath(page, root)
                    if helps[subcommand] is None:
                        findings.append(f"{relative}: 'hindsight {subcommand}' is not a subcommand")
                        continue
                    for flag in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", rest):
                        if not re.search(re.escape(flag) + r"\b", helps[subcommand]):
                            findings.append(f"{relative}: 'hindsight {subcommand} {flag}' is not in its --help")
    return findings


def check_reference(root, cli):
    """Every subcommand of `hindsight --help` and every flag of its --help appear in the CLI reference."""
    findings = []
    page = os.path.join(root, "docs", "reference", "cli.md")
    with open(page, encoding="utf-8") as f:
        reference = f.read()
    top = subprocess.run([cli, "--help"], capture_output=True, text=True).stdout
    subcommands = re.findall(r"^  ([a-z]+)\s", re.split(r"(?i)subcommands:", top, 1)[-1], re.M)
    if not subcommands:
        return [f"{cli} --help lists no subcommands"]
    for subcommand in subcommands:
        if f"## `hindsight {subcommand}`" not in reference:
            findings.append(f"docs/reference/cli.md: no section '## `hindsight {subcommand}`'")
        text = subprocess.run([cli, subcommand, "--help"], capture_output=True, text=True).stdout
        for flag in sorted(set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", text))):
            if flag != "--help" and not re.search(re.escape(flag) + r"(?![\w-])", reference):
                findings.append(f"docs/reference/cli.md: 'hindsight {subcommand} {flag}' is not documented")
    return findings


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", required=True)
    parser.add_argument("--cli")
    parser.add_argument("--only", default="paths,issues,blocks,flags")
    args = parser.parse_args()
    root = os.path.abspath(args.root)
    wanted = set(args.only.split(","))
    files = list(text_files(root))
    findings = []
    if "paths" in wanted:
        findings += check_paths(root, files)
    if "issues" in wanted:
        findings += check_issues(files)
    if "blocks" in wanted:
        findings += check_blocks(root)
    if "flags" in wanted and args.cli:
        findings += check_flags(root, args.cli) + check_reference(root, args.cli)
    for finding in findings:
        print(finding)
    print(f"check_docs: {len(files)} files, {len(findings)} findings ({args.only})")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
