"""The parent side of the background compile's helper protocol, with fake processes (no compile):
answers are read only from lines of the protocol, a helper that answered, idled and ended is
noticed and replaced, and a request that could not be sent is not left waiting forever."""

import os
from types import SimpleNamespace

import pytest

from hyst_gym.physics import background_compile as bc


class _Pipe:
    """A non-blocking pipe whose read end stands in for the helper's stdout."""

    def __init__(self, text: bytes):
        read, write = os.pipe()
        os.write(write, text)
        os.close(write)
        os.set_blocking(read, False)
        self.read = read

    def fileno(self):
        return self.read


def _helper_with(stdout_text: bytes, status, requests):
    helper = bc.CompileHelper()
    helper.process = SimpleNamespace(stdout=_Pipe(stdout_text), poll=lambda: status, returncode=status)
    helper.requests = dict(requests)
    helper._numbers = max(requests.values(), default=-1) + 1
    return helper


def test_only_protocol_lines_are_answers():
    """A library's print on the helper's stdout (numba's cache log) is skipped, not parsed as an answer."""
    helper = _helper_with(b"[cache] index saved to /x/y.nbi\ndone 0\nfailed 1 TypingError: no\nfailed 2\n", None,
                          {"a": 0, "b": 1, "c": 2})
    helper._read_answers()
    assert helper.answers == {0: bc.DONE, 1: "TypingError: no", 2: "no reason given"}
    assert helper._all_answered()


def test_helper_that_answered_and_idled_out_is_seen_as_ended():
    """Its last answer is still in the pipe when it has exited: reading it first shows every request answered,
    so the next request starts a new helper instead of writing to a dead one."""
    helper = _helper_with(b"done 0\n", 0, {"a": 0})
    assert helper._idle_and_ended()
    still_working = _helper_with(b"", 0, {"a": 0})
    assert not still_working._idle_and_ended()
    crashed = _helper_with(b"", 1, {"a": 0})
    assert not crashed._idle_and_ended()


def test_request_not_sent_is_dropped_and_numbers_are_not_reused():
    helper = _helper_with(b"done 0\n", None, {"a": 0})

    def broken_write(_data):
        raise BrokenPipeError("gone")

    helper.process.stdin = SimpleNamespace(write=broken_write, flush=lambda: None)
    dispatcher = SimpleNamespace(py_func=test_request_not_sent_is_dropped_and_numbers_are_not_reused)
    answer = helper._request(dispatcher, ("float64",))
    assert answer == "the background compile process has ended"
    assert list(helper.requests.values()) == [0]
    assert helper._numbers == 2  # the number of the unsent request is not given out again


@pytest.mark.parametrize("mode", ["bogus", "Background"])
def test_unknown_mode_names_the_variable(monkeypatch, mode):
    monkeypatch.setenv(bc.MODE_VARIABLE, mode)
    with pytest.raises(ValueError, match=bc.MODE_VARIABLE):
        bc.effective_mode()


def test_background_falls_back_to_foreground_where_the_twin_cannot_stand_in(monkeypatch):
    monkeypatch.setenv(bc.MODE_VARIABLE, bc.BACKGROUND)
    monkeypatch.setattr(bc.numba_config, "USING_SVML", True)
    assert bc.effective_mode() == bc.FOREGROUND
    monkeypatch.setattr(bc.numba_config, "USING_SVML", False)
    expected = bc.BACKGROUND if os.name == "posix" and not bc.numba_config.DISABLE_JIT else bc.FOREGROUND
    assert bc.effective_mode() == expected
    monkeypatch.setenv(bc.MODE_VARIABLE, bc.PYTHON)
    assert bc.effective_mode() == bc.PYTHON


PROBE_KERNEL = '''
from hyst_gym.physics.background_compile import background_kernel


@background_kernel()
def lock_probe(x):
    total = 0.0
    for i in range(10):
        total += x * i
    return total
'''


def test_helpers_of_several_processes_compile_a_kernel_once(tmp_path):
    """Two interpreters' helpers asked for the same kernel at the same moment (a SubprocVecEnv's workers):
    one compiles it into the shared cache, the other waits on the kernel's lock file and loads it. Without
    the lock both would compile at once (each answering a plain ``done``)."""
    import base64
    import json
    import pickle
    import subprocess
    import sys

    from numba.core import types

    (tmp_path / "lock_probe_module.py").write_text(PROBE_KERNEL)
    env = {**os.environ, bc.MODE_VARIABLE: bc.FOREGROUND, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           bc.PATH_VARIABLE: json.dumps([str(tmp_path), *sys.path])}
    request = base64.b64encode(pickle.dumps((0, "lock_probe_module", "lock_probe", (types.float64,)))) + b"\n"
    helpers = [subprocess.Popen([sys.executable, "-c", bc.HELPER_CODE], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env) for _ in range(2)]
    for helper in helpers:
        helper.stdin.write(request)
        helper.stdin.flush()
    for helper in helpers:
        helper.stdin.close()  # each helper answers what it was asked, then ends
    answers = []
    for helper in helpers:
        out, err = helper.stdout.read(), helper.stderr.read()
        assert helper.wait(timeout=300) == 0, err.decode()[-2000:]
        answers.append(out.decode().strip())
    assert sorted(answers) == ["done 0", "done 0 loaded"]
    assert bc.ANSWER_PATTERN.fullmatch("done 0 loaded").group(1) == "done"
    assert len(list((tmp_path / "cache").rglob("*lock_probe*.nbc"))) == 1


@pytest.mark.parametrize("previous", [None, bc.PYTHON])
def test_foreground_compiles_sets_the_mode_and_gives_back_the_previous(monkeypatch, previous):
    """What speed measurements run under: foreground within the block, the user's setting (or none) after it,
    also when the block raises."""
    if previous is None:
        monkeypatch.delenv(bc.MODE_VARIABLE, raising=False)
    else:
        monkeypatch.setenv(bc.MODE_VARIABLE, previous)
    with pytest.raises(RuntimeError), bc.foreground_compiles():
        assert bc.effective_mode() == bc.FOREGROUND
        raise RuntimeError("stop")
    assert os.environ.get(bc.MODE_VARIABLE) == previous
