"""tools/scripts/atomic_save.py: the previous file survives a failed save, no temporary remains.

Run by test_io (AtomicSave.PythonHelper) as: python3 atomic_save_test.py SCRIPTS_DIR
"""

import errno
import os
import resource
import signal
import stat
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, sys.argv.pop(1))
import atomic_save  # noqa: E402


class FailingFigure:
    """A figure whose savefig writes part of the file and then fails (as on a full disk)."""

    def savefig(self, path, **kwargs):
        with open(path, "wb") as f:
            f.write(b"\x89PNG partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


class GoodFigure:
    def __init__(self):
        self.kwargs = None

    def savefig(self, path, **kwargs):
        self.kwargs = kwargs
        with open(path, "wb") as f:
            f.write(b"new figure")


class AtomicSaveTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.TemporaryDirectory()
        self.path = os.path.join(self.dir.name, "fig.png")
        with open(self.path, "wb") as f:
            f.write(b"old figure")

    def tearDown(self):
        self.dir.cleanup()

    def assertOnlyTheFile(self):
        self.assertEqual(os.listdir(self.dir.name), ["fig.png"])

    def test_success_replaces_and_passes_the_format(self):
        fig = GoodFigure()
        atomic_save.savefig(fig, self.path, dpi=150)
        with open(self.path, "rb") as f:
            self.assertEqual(f.read(), b"new figure")
        self.assertEqual(fig.kwargs, {"dpi": 150, "format": "png"})
        self.assertOnlyTheFile()

    def test_failing_savefig_keeps_the_previous_file(self):
        with self.assertRaises(OSError):
            atomic_save.savefig(FailingFigure(), self.path)
        with open(self.path, "rb") as f:
            self.assertEqual(f.read(), b"old figure")
        self.assertOnlyTheFile()

    def test_file_size_limit_keeps_the_previous_file(self):
        old_limit = resource.getrlimit(resource.RLIMIT_FSIZE)
        old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, old_limit[1]))
        try:
            with self.assertRaises(OSError) as raised:
                atomic_save.write_text(self.path, "x" * 100000)
        finally:
            resource.setrlimit(resource.RLIMIT_FSIZE, old_limit)
            signal.signal(signal.SIGXFSZ, old_handler)
        self.assertEqual(raised.exception.errno, errno.EFBIG)
        with open(self.path, "rb") as f:
            self.assertEqual(f.read(), b"old figure")
        self.assertOnlyTheFile()

    def test_fifo_is_refused_not_replaced(self):
        # Issue 38 item 1, on a scratch FIFO (never the machine's /dev/null).
        fifo = os.path.join(self.dir.name, "fifo")
        os.mkfifo(fifo)
        with self.assertRaises(OSError) as raised:
            atomic_save.write_text(fifo, "text")
        self.assertEqual(raised.exception.filename, fifo)
        self.assertTrue(stat.S_ISFIFO(os.stat(fifo).st_mode))
        self.assertEqual(sorted(os.listdir(self.dir.name)), ["fifo", "fig.png"])

    def test_stop_signals_remove_the_temporaries(self):
        # Issue 38 item 7: SIGTERM during `plot` or `report` left *.tmp-PID-N files.
        child = ("import os, signal, sys; sys.path.insert(0, %r); import atomic_save\n"
                 "with atomic_save.atomic_path(%r) as tmp:\n"
                 "    open(tmp, 'w').write('partial')\n"
                 "    print('ready', flush=True)\n"
                 "    signal.pause()\n" % (os.path.dirname(atomic_save.__file__), self.path))
        for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            proc = subprocess.Popen([sys.executable, "-c", child], stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE,
                                    preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                     signal.default_int_handler))
            self.assertEqual(proc.stdout.readline(), b"ready\n")
            proc.send_signal(signum)
            _, err = proc.communicate()
            self.assertEqual(proc.returncode, 128 + signum, err)
            self.assertNotIn(b"Traceback", err)
            self.assertOnlyTheFile()
        with open(self.path, "rb") as f:
            self.assertEqual(f.read(), b"old figure")


if __name__ == "__main__":
    unittest.main()
