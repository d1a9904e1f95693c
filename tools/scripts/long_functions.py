#!/usr/bin/env python3
"""Functions longer than a limit (default 80 lines) in the C++ of core/ and tools/.

Usage: long_functions.py [--limit N] [--allowed FILE] [PATH ...]     (default paths: core tools)

universal-ctags (Debian universal-ctags, scripts/setup.sh installs it) gives every function
definition's first and last line (--fields=+ne), in every file: pmccabe silently skips files that
open with `namespace a::b {`. Lambdas count (ctags names them __anon...), headers are read as C++.

Prints one line per function over the limit, longest first: "LINES FILE:LINE NAME". With
--allowed, a file of "FILE NAME LINES" lines (the known offenders, to be shortened), a listed
function may stay over the limit but not grow, and a listed function that no longer exceeds it
must leave the list. Exit 0: nothing over the limit beyond the list; 1: an offender (or a stale or
grown entry), each named; 2: usage error or no universal-ctags.
"""
import argparse
import os
import shutil
import subprocess
import sys

SUFFIXES = (".cpp", ".cc", ".h", ".hpp")


def source_files(paths):
    files = []
    for path in paths:
        if os.path.isfile(path):
            files.append(path)
            continue
        for root, _, names in os.walk(path):
            files += [os.path.join(root, n) for n in sorted(names) if n.endswith(SUFFIXES)]
    return sorted(files)


def functions(files):
    """(lines, file, line, name) of every function definition ctags finds."""
    ctags = shutil.which("ctags-universal") or shutil.which("ctags")
    if ctags is None:
        raise RuntimeError("no universal-ctags (apt-get install universal-ctags)")
    command = [ctags, "--fields=+ne", "--c++-kinds=f", "--languages=C++", "--langmap=C++:+.h",
               "-o", "-"] + files
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    result = []
    for row in out.splitlines():
        cells = row.split("\t")
        fields = dict(c.split(":", 1) for c in cells[3:] if ":" in c)
        if "line" in fields and "end" in fields:
            start, end = int(fields["line"]), int(fields["end"])
            result.append((end - start + 1, cells[1], start, cells[0]))
    return result


def read_allowed(path):
    allowed = {}
    with open(path) as f:
        for number, text in enumerate(f, 1):
            text = text.split("#", 1)[0].strip()
            if not text:
                continue
            parts = text.split()
            if len(parts) != 3 or not parts[2].isdigit():
                raise ValueError(f"{path}:{number}: expected FILE NAME LINES, got {text!r}")
            allowed[(parts[0], parts[1])] = int(parts[2])
    return allowed


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=int, default=80)
    parser.add_argument("--allowed", help="known offenders: FILE NAME LINES per line")
    parser.add_argument("paths", nargs="*", default=["core", "tools"])
    args = parser.parse_args(argv[1:])
    try:
        found = functions(source_files(args.paths))
        allowed = read_allowed(args.allowed) if args.allowed else {}
    except (RuntimeError, ValueError, OSError, subprocess.CalledProcessError) as e:
        print(f"long_functions: {e}", file=sys.stderr)
        return 2
    problems = []
    over = sorted((f for f in found if f[0] > args.limit), reverse=True)
    for lines, path, line, name in over:
        print(f"{lines} {path}:{line} {name}")
        budget = allowed.get((path, name))
        if budget is None:
            problems.append(f"{path}:{line}: {name} has {lines} lines, over {args.limit}")
        elif lines > budget:
            problems.append(f"{path}:{line}: {name} grew to {lines} lines (listed with {budget})")
    still_long = {(path, name) for _, path, _, name in over}
    for key in sorted(set(allowed) - still_long):
        problems.append(f"{args.allowed}: {key[0]} {key[1]} is no longer over {args.limit} "
                        f"lines: remove it from the list")
    for p in problems:
        print(f"long_functions: {p}", file=sys.stderr)
    print(f"{len(over)} function(s) over {args.limit} lines in {len(found)} "
          f"({len(over) - sum(1 for k in still_long if k in allowed)} not listed)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
