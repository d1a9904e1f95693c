#!/usr/bin/env python3
"""Checks that one ISA's kernel object (core/isa_kernels.cmake) shares no code with the others.

usage: check_isa_object.py OBJECT NAMESPACE     e.g. marglab_isa_avx2.o isa_avx2

The object is the partial link of one ISA's kernel sources with its hidden symbols made local.
It passes when
  - the only symbol it defines globally is marglab::NAMESPACE::kernels() (every Eigen instantiation
    and every marglab function compiled for this ISA is local: the linker cannot swap it for
    another ISA's copy, nor another ISA's code for it), and
  - it refers to no symbol it does not define that is Eigen's or weak (an inline or template
    function it did not compile itself would bind to some other object's copy), and
  - it calls no plain allocator (malloc and calloc are renamed to marglab_isa_aligned_malloc /
    _calloc: Eigen's AVX code assumes its buffers aligned to the vector width, and its loops that
    peel to the first aligned coefficient would otherwise follow the heap's layout).
On failure it prints the offending symbols, removes OBJECT (so that the build step reruns) and
exits 1.
"""
import os
import subprocess
import sys


def nm(path, *flags):
    out = subprocess.run(["nm", "-C", *flags, path], check=True, capture_output=True, text=True)
    rows = []
    for line in out.stdout.splitlines():
        parts = line.split(None, 2) if line[:1] != " " else ["", *line.split(None, 1)]
        if len(parts) == 3:
            rows.append((parts[1], parts[2]))
    return rows


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    path, namespace = sys.argv[1], sys.argv[2]
    entry = f"marglab::{namespace}::kernels()"
    problems = []
    exported = [name for kind, name in nm(path, "--defined-only", "--extern-only")]
    if exported != [entry]:
        problems += [f"exported: {name}" for name in exported if name != entry]
        if entry not in exported:
            problems.append(f"missing export: {entry}")
    for kind, name in nm(path, "--undefined-only"):
        if name.startswith("Eigen::") or kind in ("w", "v"):
            problems.append(f"refers to a symbol defined elsewhere: {kind} {name}")
        if name in ("malloc", "calloc", "realloc", "reallocarray", "aligned_alloc", "memalign",
                    "valloc", "pvalloc"):
            problems.append(f"calls {name} (not renamed to a marglab_isa_aligned_* allocator)")
    if problems:
        print(f"{path}: not isolated:\n  " + "\n  ".join(problems[:40]), file=sys.stderr)
        os.remove(path)
        sys.exit(1)


if __name__ == "__main__":
    main()
