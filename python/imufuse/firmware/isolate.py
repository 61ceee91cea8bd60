"""``validate_isolated``: validation on the host with the firmware in a child process and a
timeout. A crash (signal), a call to exit() or a run past the timeout becomes one line naming
the sample, found by re-running on shorter prefixes."""
import multiprocessing
import signal

from .declaration import FirmwareError
from .validate import _c_values, _filter_entry, validate

__all__ = ["validate_isolated", "DEFAULT_TIMEOUT"]

#: seconds a firmware run may take in validate_isolated (imufuse validate --timeout)
DEFAULT_TIMEOUT = 60.0

#: _attempt's n for "load the firmware and stop" (its constructors only)
LOAD_ONLY = -1


def _child(conn, fw, name, params, inputs, backend, dtype, n, explain=True):  # host only
    try:
        if n == LOAD_ONLY:
            # the firmware's C constructors run when it is loaded, before init
            e = _filter_entry(name)
            fw.load(e.kind, _c_values(e, params), params)
            conn.send(("ok", None))
            return
        inp = inputs if n is None else [a[:n] for a in inputs]
        conn.send(("ok", validate(fw, name, params, inp, backend, dtype, explain=explain)))
    except FirmwareError as e:
        conn.send(("firmware", str(e)))
    except Exception as e:  # noqa: BLE001 - reported to the parent as one line
        conn.send(("error", f"{type(e).__name__}: {e}"))
    finally:
        conn.close()


def _attempt(fw, name, params, inputs, backend, dtype, n, timeout, explain=True):
    """One run in a child: ("ok", Validation) | ("firmware"|"error", msg) |
    ("signal", signum) | ("exit", code) | ("timeout", None)."""
    ctx = multiprocessing.get_context("fork")
    r, w = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(w, fw, name, params, inputs, backend, dtype, n, explain),
                    daemon=True)
    p.start()
    w.close()
    try:
        msg = None
        if r.poll(timeout):
            try:
                msg = r.recv()
            except (EOFError, OSError):
                msg = None
        if msg is not None:
            p.join(5)
            return msg
        p.join(0.5 if p.is_alive() else 5)
        # a child that answered just after the timeout (a loaded machine) has said how it
        # ended, exited or not yet: its answer, not its exit code 0 or a kill, is the outcome
        try:
            if r.poll(0):
                return r.recv()
        except (EOFError, OSError):
            pass
        if p.is_alive():
            p.kill()
            p.join(5)
            return ("timeout", None)
        code = p.exitcode
        return ("signal", -code) if code is not None and code < 0 else ("exit", code)
    finally:
        r.close()
        if p.is_alive():
            p.kill()
            p.join(5)


def _describe(res, where, timeout):
    kind, v = res
    if kind == "signal":
        try:
            sig = signal.Signals(v).name
        except ValueError:
            sig = f"signal {v}"
        return f"the firmware crashed with {sig} {where}"
    if kind == "exit":
        return f"the firmware called exit({v}) {where}"
    if kind == "timeout":
        if where:
            return f"the firmware gave no answer after {timeout:g} s {where}"
        return f"the firmware gave no answer after {timeout:g} s (an endless loop in init or update?)"
    return v


def validate_isolated(fw, name, params, inputs, backend="c", dtype=None, timeout=DEFAULT_TIMEOUT,
                      target="host", explain=True):
    """validate() with the firmware in a child process and a timeout.

    A crash (signal), a call to exit() or a run past `timeout` seconds raises
    FirmwareError with one line: "crashed with SIGSEGV at sample k" (found by
    re-running on shorter prefixes) or "during init", "while being loaded" (a C
    constructor), "called exit(3) ...", "no answer after N s". Compilation happens first,
    in this process; the firmware is loaded only in the child, so no firmware code (not
    even a C constructor) runs here."""
    if target != "host":
        return validate(fw, name, params, inputs, backend, dtype, target=target, timeout=timeout,
                        explain=explain)
    e = _filter_entry(name)
    fw.prepare(e.kind, _c_values(e, params), params)
    res = _attempt(fw, name, params, inputs, backend, dtype, None, timeout, explain)
    if res[0] == "ok":
        return res[1]
    if res[0] in ("firmware", "error"):
        raise FirmwareError(res[1])
    def prefix(n):
        r = _attempt(fw, name, params, inputs, backend, dtype, n, timeout, explain=False)
        if r[0] == "timeout" and res[0] != "timeout":
            # the full run failed otherwise (a crash, an exit) within the timeout: a prefix
            # that only ran out of time did so on a loaded machine, and given more time it
            # fails the same way or passes
            r = _attempt(fw, name, params, inputs, backend, dtype, n, 10 * timeout,
                         explain=False)
        return r

    # the firmware's own code failed: first its C constructors (run when it is loaded)
    loaded = prefix(LOAD_ONLY)
    if loaded[0] in ("firmware", "error"):
        raise FirmwareError(loaded[1])
    if loaded[0] != "ok":
        raise FirmwareError(_describe(loaded, "while being loaded, before init (a C "
                                      "constructor or a static C++ object)", timeout))
    if res[0] == "timeout":
        raise FirmwareError(_describe(res, "", timeout))
    # locate the sample: the shortest prefix that fails the same way
    first = prefix(0)
    if first[0] not in ("ok", "firmware", "error"):
        raise FirmwareError(_describe(first, "during init", timeout))
    lo, hi = 0, len(inputs[0])          # run(lo) succeeds, run(hi) fails
    while hi - lo > 1:
        mid = (lo + hi) // 2
        r = prefix(mid)
        if r[0] in ("ok", "firmware", "error"):
            lo = mid
        else:
            hi, res = mid, r
    raise FirmwareError(_describe(res, f"at sample {hi - 1}", timeout))
