"""Kernels that do not keep the first step waiting for the compiler: :func:`background_kernel`.

A numba kernel compiles on its first call and is then cached on disk. An environment's step
kernels take 10-30 s to compile on 2 cores, so a fresh install's first ``env.step`` waited that
long. A :func:`background_kernel` is a numba dispatcher (it compiles, caches and is called from
other kernels exactly as ``njit`` makes it) whose first call from Python, when its compiled code
is neither in memory nor in numba's disk cache, does not compile there and then. It asks one
helper process per interpreter (:func:`serve`, a fresh ``python``) to compile it
into that same cache, and meanwhile runs the kernel's :func:`python_twin`: its ``py_func`` with
every kernel it calls replaced by their own twins. The twin does the same IEEE double
arithmetic in the same order as the compiled code (numba's default: no fastmath, so no
reassociation or fused multiply-add), so the numbers are the same bit for bit
(``tests/envs/test_background_compile.py`` runs the environments both ways); it is roughly
100x slower per step. The first call after the helper has written the cache loads it, and from then on the
kernel runs compiled.

The environment variable ``HYST_GYM_COMPILE`` chooses (read at each such first call):

* ``background`` (default): as above;
* ``foreground``: compile on the first call, as plain numba (what speed measurements want);
* ``python``: never compile; always the twin (debugging, and the bit-for-bit test).

A speed measurement runs inside :func:`foreground_compiles`, so that it never times the twins.

Where the helper fails, or its cache cannot be read here, the kernel compiles in the foreground
after one line on stderr that says so.

Several interpreters (the worker processes of a ``SubprocVecEnv``, say) each start a helper, but a
kernel is compiled by one of them at a time: a helper takes a lock file per kernel and signature
(:func:`compile_lock`) and, holding it, loads what another helper wrote meanwhile instead of
compiling it again. Eight workers on two cores compile each kernel once, not eight times at once.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import importlib
import json
import os
import pickle
import re
import select
import subprocess
import sys
import tempfile
import threading
import time
import types as python_types

from numba.core import config as numba_config
from numba.core import types
from numba.core.compiler_lock import global_compiler_lock
from numba.core.dispatcher import Dispatcher, OmittedArg
from numba.core.registry import CPUDispatcher

#: the environment variable that chooses how background kernels compile, and its values
MODE_VARIABLE = "HYST_GYM_COMPILE"
BACKGROUND, FOREGROUND, PYTHON = "background", "foreground", "python"
MODES = (BACKGROUND, FOREGROUND, PYTHON)
#: the helper's answers to a request, besides why it could not compile it
PENDING, DONE = None, ""
#: the helper's ``sys.path`` (the parent's), so that it imports the same files the parent runs
PATH_VARIABLE = "HYST_GYM_COMPILE_PATH"
#: a helper with nothing to compile for this long (s) ends; the next request starts another
HELPER_IDLE_SECONDS = 60.0
#: the helper's program: the parent's sys.path first, then :func:`serve`
#: an answer line of the helper: ``done N`` or ``failed N why`` (``done N loaded``: another helper had
#: compiled it into the cache, and this one loaded it)
ANSWER_PATTERN = re.compile(r"(done|failed) (\d+)(?: (.*))?")
HELPER_CODE = ("import json, os, sys; sys.path[:0] = json.loads(os.environ['HYST_GYM_COMPILE_PATH']); "
               "from hyst_gym.physics.background_compile import serve; serve()")


def compile_mode() -> str:
    """The value of ``HYST_GYM_COMPILE`` (default ``background``); a ValueError naming it otherwise."""
    mode = os.environ.get(MODE_VARIABLE, BACKGROUND) or BACKGROUND
    if mode not in MODES:
        raise ValueError(f"{MODE_VARIABLE}={mode!r} is not one of {', '.join(MODES)}")
    return mode


def effective_mode() -> str:
    """What a background kernel's first call does here: :func:`compile_mode`, except that ``background``
    compiles in the foreground where the twin cannot stand in for the compiled code: no POSIX pipes and
    sessions for the helper (Windows), numba's JIT switched off, or Intel's SVML math in use (its
    vectorized functions can differ from the C library's, which the twin calls, in the last bit)."""
    mode = compile_mode()
    if mode == BACKGROUND and (numba_config.DISABLE_JIT or os.name != "posix" or numba_config.USING_SVML):
        return FOREGROUND
    return mode


@contextlib.contextmanager
def foreground_compiles():
    """Within this block, background kernels compile on their first call (``HYST_GYM_COMPILE=foreground``),
    as a speed measurement needs: in the background its first calls would time the plain-Python twins,
    about 100x slower. The variable's previous value (or its absence) comes back after the block; it is
    process-wide while the block runs."""
    previous = os.environ.get(MODE_VARIABLE)
    os.environ[MODE_VARIABLE] = FOREGROUND
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(MODE_VARIABLE, None)
        else:
            os.environ[MODE_VARIABLE] = previous


def python_twin(kernel, _twins=None, _namespaces=None):
    """The plain-Python form of numba kernel ``kernel`` (a dispatcher, or a plain function).

    Its ``py_func``, run in a copy of its module's globals in which every numba dispatcher is
    replaced by its own twin (recursively; one namespace copy per module). Plain Python calls
    the same functions in the same order on float64 values, so it computes what the compiled
    kernel computes, bit for bit (``NUMBA_DISABLE_JIT=1`` is the same substitution, for a whole
    process). A kernel reached otherwise than through a module global (a closure, a module
    attribute) stays the dispatcher and compiles when called."""
    twins = {} if _twins is None else _twins
    namespaces = {} if _namespaces is None else _namespaces
    function = kernel.py_func if isinstance(kernel, Dispatcher) else kernel
    if function in twins:
        return twins[function]
    module_globals = function.__globals__
    fresh = id(module_globals) not in namespaces
    if fresh:
        namespaces[id(module_globals)] = dict(module_globals)
    namespace = namespaces[id(module_globals)]
    twin = python_types.FunctionType(function.__code__, namespace, function.__name__, function.__defaults__,
                              function.__closure__)
    twin.__kwdefaults__ = function.__kwdefaults__
    twin.__doc__, twin.__qualname__, twin.__module__ = function.__doc__, function.__qualname__, function.__module__
    twins[function] = twin
    if fresh:
        for name, value in list(namespace.items()):
            if isinstance(value, Dispatcher):
                namespace[name] = python_twin(value, twins, namespaces)
    return twin


class BackgroundDispatcher(CPUDispatcher):
    """numba's CPU dispatcher, with the first call of a new signature as described in the module
    docstring. numba's C dispatcher calls :meth:`_compile_for_args` only when no compiled
    overload matches the arguments, and then calls what it returns with them: the compiled
    entry point, or here, until that exists, the python twin. Calls that match a compiled
    overload never reach Python, so the compiled speed is numba's own."""

    def _compile_for_args(self, *args, **kws):
        mode = effective_mode()
        if mode == FOREGROUND or kws:
            return super()._compile_for_args(*args, **kws)
        if mode == PYTHON:
            return self._twin_call
        self._compilation_chain_init_hook()  # as numba's _compile_for_args, before it loads or compiles
        signature = tuple(types.Omitted(arg.value) if isinstance(arg, OmittedArg) else self.typeof_pyval(arg)
                          for arg in args)
        entry_point = self._load_cached(signature)
        if entry_point is not None:
            return entry_point
        answer = helper_for_this_process().request(self, signature)
        if answer is PENDING:
            return self._twin_call
        if answer == DONE:
            entry_point = self._load_cached(signature, again=True)
            if entry_point is not None:
                return entry_point
            answer = "the background compile wrote a cache this process does not read"
        print(f"hyst-gym: {answer}; compiling {self.py_func.__qualname__} here instead", file=sys.stderr,
              flush=True)
        return super()._compile_for_args(*args)

    def _twin_call(self, *args):
        if not hasattr(self, "_twin"):
            self._twin = python_twin(self)
        return self._twin(*(arg.value if isinstance(arg, OmittedArg) else arg for arg in args))

    def _load_cached(self, signature, again: bool = False):
        """The entry point of ``signature`` loaded from numba's disk cache, or None where it is not
        there (yet). The cache is read again only when its index file has changed (``os.stat``) or
        ``again`` (numba writes the index before the compiled code, so a changed index can still
        miss it)."""
        stamp = _index_stamp(self)
        if not again and stamp is not None and getattr(self, "_missed_stamp", None) == (signature, stamp):
            return None
        # numba's Dispatcher.compile, its cache-loading branch (the rest of it compiles)
        with global_compiler_lock:
            result = self._cache.load_overload(signature, self.targetctx)
            if result is None:
                self._missed_stamp = (signature, stamp)
                return None
            self._cache_hits[signature] += 1
            self.targetctx.insert_user_function(result.entry_point, result.fndesc, [result.library])
            self.add_overload(result)
            return result.entry_point


def _index_stamp(dispatcher):
    """(mtime, size) of the dispatcher's numba cache index, None where there is none or it cannot
    be found (numba's cache object is internal)."""
    try:
        status = os.stat(dispatcher._cache._cache_file._index_path)
    except (AttributeError, OSError):
        return None
    return status.st_mtime_ns, status.st_size


def background_kernel(*, cache: bool = True, **options):
    """``numba.njit(cache=cache, **options)``, made a :class:`BackgroundDispatcher`. Use it on the
    kernels that Python calls first (an environment's make, reset and step); the kernels they
    call stay plain ``njit``."""
    def decorate(function):
        if numba_config.DISABLE_JIT:
            return function
        dispatcher = BackgroundDispatcher(py_func=function, locals={}, targetoptions={"nopython": True, **options})
        if cache:
            dispatcher.enable_caching()
        return dispatcher
    return decorate


class CompileHelper:
    """The helper process of one interpreter and what it was asked to compile.

    Requests go to its stdin, one line each (base64 of a pickled number, module, qualified name
    and numba signature); it answers ``done N`` or ``failed N why`` on stdout, which this side
    reads without blocking. It runs in its own session, so it finishes what it was asked (and the
    disk cache with it) after this interpreter exits, and then ends (its stdin closes)."""

    def __init__(self):
        self.pid = os.getpid()
        self.process = None
        self.requests: dict = {}  # (module, qualname, signature) -> request number
        self.answers: dict = {}  # request number -> DONE or why it failed
        self._numbers = 0  # request numbers are never reused, so an answer always names its own request
        self._unread = b""
        self._lock = threading.Lock()  # threads of one process share the helper and its pipes

    def _start(self) -> str | None:
        """Start a helper; None, or why it could not be started."""
        env = {**os.environ, MODE_VARIABLE: FOREGROUND, PATH_VARIABLE: json.dumps(sys.path)}
        try:
            self.process = subprocess.Popen([sys.executable, "-c", HELPER_CODE], stdin=subprocess.PIPE,
                                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                                            start_new_session=True)
        except OSError as error:
            return f"the background compile process could not start ({error})"
        os.set_blocking(self.process.stdout.fileno(), False)
        self._unread = b""
        return None

    def _all_answered(self) -> bool:
        return all(number in self.answers for number in self.requests.values())

    def _idle_and_ended(self) -> bool:
        """Whether the helper has ended by itself, idle (every request answered, status 0). Its last
        answers are read first: it may have answered, idled and ended since the last look."""
        if self.process.poll() != 0:
            return False
        self._read_answers()
        return self._all_answered()

    def request(self, dispatcher, signature) -> str | None:
        """Ask for ``dispatcher`` at ``signature`` (once). :data:`PENDING` while the helper works on
        it, :data:`DONE` when it has compiled it, else why it cannot (it failed or has ended)."""
        with self._lock:
            return self._request(dispatcher, signature)

    def _request(self, dispatcher, signature) -> str | None:
        key = (dispatcher.py_func.__module__, dispatcher.py_func.__qualname__, signature)
        if key not in self.requests:
            if self.process is None or self._idle_and_ended():
                problem = self._start()
                if problem:
                    return problem
            number = self._numbers
            self._numbers += 1
            self.requests[key] = number
            try:
                self.process.stdin.write(base64.b64encode(pickle.dumps((number, *key))) + b"\n")
                self.process.stdin.flush()
            except OSError:
                del self.requests[key]  # not sent: the next call asks a new helper
                return "the background compile process has ended"
        self._read_answers()
        number = self.requests[key]
        if number in self.answers:
            why = self.answers[number]
            return DONE if why == DONE else f"the background compile failed ({why})"
        if self.process.poll() is not None:
            return f"the background compile process ended (status {self.process.returncode})"
        return PENDING

    def _read_answers(self):
        try:
            self._unread += os.read(self.process.stdout.fileno(), 1 << 16)
        except BlockingIOError:
            return
        *lines, self._unread = self._unread.split(b"\n")
        for line in lines:
            # only the helper's answers; anything else a library printed there is not ours to read
            answer = ANSWER_PATTERN.fullmatch(line.decode(errors="replace"))
            if answer:
                verdict, number, why = answer.groups()
                self.answers[int(number)] = DONE if verdict == "done" else why or "no reason given"

    def wait(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s until every request is answered; whether they all are."""
        deadline = time.monotonic() + timeout
        while self.process is not None and not self._all_answered():
            with self._lock:
                self._read_answers()
            if self.process.poll() is not None or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        return self.process is None or self._all_answered()


#: the helper of this interpreter, made on the first request. Module state because it is one per
#: process, as numba's own compiled code is; a forked child (multiprocessing) makes its own, since
#: it must not read the parent's answers.
_helper: CompileHelper | None = None


def helper_for_this_process() -> CompileHelper:
    global _helper
    if _helper is None or _helper.pid != os.getpid():
        _helper = CompileHelper()
    return _helper


def wait_for_background_compiles(timeout: float = 600.0) -> bool:
    """Block until the helper has answered every request of this process (or ``timeout`` s); whether
    it has. The next call of each kernel then loads its compiled code."""
    return _helper is None or _helper.pid != os.getpid() or _helper.wait(timeout)


def serve(idle_seconds: float = HELPER_IDLE_SECONDS) -> None:
    """The helper process: compile each requested kernel into numba's disk cache and answer, until
    stdin closes (the parent has exited) or ``idle_seconds`` pass without a request."""
    stdin, unread = sys.stdin.buffer.fileno(), b""
    # the answers get their own copy of stdout; stdout itself goes to stderr, so that whatever the compile
    # prints (numba's cache log, a library's warning) never reaches the parent as an answer
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "w")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    while True:
        if b"\n" not in unread:
            if not select.select([stdin], [], [], idle_seconds)[0]:
                return
            chunk = os.read(stdin, 1 << 16)
            if not chunk:
                return
            unread += chunk
            continue
        line, unread = unread.split(b"\n", 1)
        answer = _compile_request(line)
        try:
            print(answer, file=answers, flush=True)
        except OSError:  # the parent has exited: go on compiling what it asked for, into the cache
            pass


def compile_lock(module: str, qualname: str, signature) -> str:
    """The lock file that one helper holds while it compiles ``module.qualname`` at ``signature``: in a
    folder of this user's in the temporary directory, named by a hash of the three (numba's cache folder
    is numba's internal business)."""
    key = hashlib.sha256(repr((module, qualname, tuple(signature))).encode()).hexdigest()[:32]
    folder = os.path.join(tempfile.gettempdir(), f"hyst_gym-compile-{os.getuid()}")
    os.makedirs(folder, mode=0o700, exist_ok=True)
    return os.path.join(folder, f"{key}.lock")


def _compile_request(line: bytes) -> str:
    """Compile one request (a line from the parent) into numba's cache, holding its
    :func:`compile_lock` (numba's ``compile`` loads from the cache what another helper wrote while this
    one waited); the answer line, ``done N loaded`` when it was loaded."""
    number, module, qualname, signature = pickle.loads(base64.b64decode(line))
    try:
        kernel = importlib.import_module(module)
        for part in qualname.split("."):
            kernel = getattr(kernel, part)
        import fcntl  # POSIX only, as the helper is (effective_mode)

        with open(compile_lock(module, qualname, signature), "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or when this process ends
            hits = sum(kernel._cache_hits.values())
            kernel.compile(signature)
            loaded = sum(kernel._cache_hits.values()) > hits
        return f"done {number} loaded" if loaded else f"done {number}"
    except Exception as error:  # any failure is the parent's to report; it then compiles itself
        return f"failed {number} {type(error).__name__}: {' '.join(str(error).split())[:300]}"
