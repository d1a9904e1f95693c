"""tools/scripts/atomic_save.py: the previous file survives a failed save, no temporary remains.

Run by test_io (AtomicSave.PythonHelper) as: python3 atomic_save_test.py SCRIPTS_DIR
"""

import errno
import os
import resource
import signal
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


if __name__ == "__main__":
    unittest.main()
