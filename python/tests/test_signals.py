"""envkit's signal cleanup never takes a signal that Python (or the application) handles itself."""
import ctypes
import signal

import envkit


def c_level_handler(sig):
    """The handler address the C library holds for `sig` (Python's signal.getsignal shows only Python's view)."""
    libc = ctypes.CDLL(None, use_errno=True)
    action = ctypes.create_string_buffer(512)  # struct sigaction: the handler is its first member
    assert libc.sigaction(sig, None, action) == 0
    return ctypes.c_void_p.from_buffer(action).value


def test_writing_keeps_pythons_sigint_handler(tmp_path):
    before = c_level_handler(signal.SIGINT)
    assert before not in (None, 0, 1), "Python installs its own SIGINT handler"
    envkit.EnvMap.blank(8).write(str(tmp_path / "a.exr"))  # the first atomic write installs envkit's handlers
    assert c_level_handler(signal.SIGINT) == before
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ignored_sigpipe_stays_ignored(tmp_path):
    # Python ignores SIGPIPE (so a closed pipe is an exception): envkit leaves it ignored.
    assert signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN
    envkit.EnvMap.blank(8).write(str(tmp_path / "b.exr"))
    assert c_level_handler(signal.SIGPIPE) == 1  # SIG_IGN
