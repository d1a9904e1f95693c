"""Atomic output files for the plotting and report scripts (docs/design.md §6, "Atomicity").

As in core/common/atomic_file.h: a file is written to a temporary sibling
"<path>.tmp-<pid>-<n>" (same folder, so that the rename stays on one file system), fsynced and
renamed onto <path>. On any failure (disk full, an exception while drawing) the previous file at
<path> is untouched and the temporary is removed.
"""

import contextlib
import itertools
import os

_counter = itertools.count()


@contextlib.contextmanager
def atomic_path(path):
    """Yields the temporary's name to write; renames it onto path when the block succeeds."""
    tmp = "%s.tmp-%d-%d" % (path, os.getpid(), next(_counter))
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def savefig(fig, path, **kwargs):
    """fig.savefig(path, **kwargs), atomically; the format comes from path's extension."""
    kwargs.setdefault("format", os.path.splitext(path)[1].lstrip(".") or None)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)


def write_text(path, text):
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
