"""Atomic output files for the plotting and report scripts (docs/design.md §6, "Atomicity").

As in core/common/atomic_file.h: a file is written to a temporary sibling
"<path>.tmp-<pid>-<n>" (same folder, so that the rename stays on one file system), fsynced and
renamed onto <path>. On any failure (disk full, an exception while drawing) the previous file at
<path> is untouched and the temporary is removed. A path that is a device node, a FIFO or a
socket is refused (OSError): the rename would replace it with a regular file. SIGTERM and SIGHUP
(and SIGINT where it is still Python's default) remove the live temporaries and exit 128 + the
signal, as the C++ handler does; SIGXFSZ is ignored by Python, so a write past `ulimit -f` fails
with EFBIG and is cleaned up like any other failure.

run_main(main, name) runs a script's main without a Python traceback for the user: an OSError
(an unwritable folder, a full disk) is one line naming the file, exit 1.
"""

import contextlib
import errno
import itertools
import os
import signal
import stat
import sys

_counter = itertools.count()
_live = set()  # temporaries being written, removed by the signal handler
_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _on_stop_signal(signum, _frame):
    for tmp in list(_live):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    os.write(2, b"\n%s: interrupted by %s: stopped, unfinished outputs removed\n"
             % (os.path.basename(sys.argv[0]).encode(), signal.Signals(signum).name.encode()))
    os._exit(128 + signum)


def install_signal_cleanup():
    """Idempotent; leaves alone a signal someone else handles or ignores (as the C++ side), such
    as unwind_on_stop_signals."""
    defaults = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL,
                signal.SIGHUP: signal.SIG_DFL}
    for signum in _STOP_SIGNALS:
        if signal.getsignal(signum) is defaults[signum]:
            signal.signal(signum, _on_stop_signal)


def unwind_on_stop_signals():
    """For a script that owns more than temporaries (a browser, its profile folder): SIGINT,
    SIGTERM and SIGHUP raise SystemExit(128 + signal), so that its finally blocks run and
    atomic_path removes its temporary on the way out."""
    def stop(signum, _frame):
        raise SystemExit(128 + signum)
    for signum in _STOP_SIGNALS:
        signal.signal(signum, stop)


def refuse_special_file(path):
    """Raises OSError when path exists and is a device node, FIFO or socket."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise OSError(errno.EEXIST, "is not a regular file (a device node, FIFO or socket): the "
                      "output is written to a temporary renamed onto the path, which would "
                      "replace it; give the path of a regular file", path)


@contextlib.contextmanager
def atomic_path(path):
    """Yields the temporary's name to write; renames it onto path when the block succeeds."""
    install_signal_cleanup()
    refuse_special_file(path)
    tmp = "%s.tmp-%d-%d" % (path, os.getpid(), next(_counter))
    # Blocked while the temporary is created and registered: no signal lands in between.
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
        _live.add(tmp)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        refuse_special_file(path)  # created while the temporary was written
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        _live.discard(tmp)


def savefig(fig, path, **kwargs):
    """fig.savefig(path, **kwargs), atomically; the format comes from path's extension."""
    kwargs.setdefault("format", os.path.splitext(path)[1].lstrip(".") or None)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)


def write_text(path, text):
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)


def write_bytes(path, data):
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)


def run_main(main, name):
    """sys.exit(main()), an OSError reported as one line naming the file (exit 1)."""
    install_signal_cleanup()
    try:
        code = main()
    except OSError as e:
        where = e.filename if e.filename else ""
        print("%s: error: %s%s" % (name, where + ": " if where else "", e.strerror or e),
              file=sys.stderr)
        code = 1
    sys.exit(code)
