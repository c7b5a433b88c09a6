"""The sandbox: the only process in which student code runs.

Started by the test runner as ``python -E -s sandbox.py MODULE_FILE`` (by file path, so it
imports numpy but not mslab), in a fresh folder holding only the student's file, with
resource limits set by the runner. It

1. keeps private duplicates of stdin/stdout as its message channel and points the
   standard streams at ``/dev/null`` (printing costs time, never floods anything);
2. imports the student module and reports ``ready`` or the reason it could not;
3. answers requests ``getattr NAME`` / ``call NAME ARGS KWARGS`` with plain data
   (see :mod:`wire`): a value, or the exception's type and message.

Nothing it says decides a grade by itself: the runner checks every value in its own
process with the instructor's tests. Everything it says is the student's (student code
runs in this process and may write anything on the channel): the runner takes from a
reply only its shape (a value, an exception, data it could not encode) and quotes its
words in public tests only.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import traceback

from wire import WireError, dumps, loads


def _describe(err: BaseException, filename: str) -> str:
    """``Type: message (file.py, line N)`` pointing at the student's file when possible."""
    where = ""
    for frame in reversed(traceback.extract_tb(err.__traceback__)):
        if frame.filename == filename:
            where = f" ({os.path.basename(filename)}, line {frame.lineno})"
            break
    text = str(err).splitlines()[0][:300] if str(err) else ""
    if isinstance(err, SyntaxError):  # str() already ends with "(file, line N)": say it once
        text = str(err.msg or "").splitlines()[0][:300] if err.msg else ""
        if err.lineno:
            where = f" ({os.path.basename(filename)}, line {err.lineno})"
    return f"{type(err).__name__}: {text}{where}" if text else f"{type(err).__name__}{where}"


def _error(err: BaseException, filename: str) -> dict:
    if isinstance(err, SystemExit):
        return {"ok": False, "type": "SystemExit", "mro": ["SystemExit"],
                "error": f"the code called sys.exit({err.code!r})"}
    return {"ok": False, "type": type(err).__name__, "mro": [c.__name__ for c in type(err).__mro__],
            "error": _describe(err, filename)}


def main() -> None:
    """Import the student's file (``sys.argv[1]``) and answer calls on the channel until it closes."""
    filename = os.path.abspath(sys.argv[1])
    chan_in = os.fdopen(os.dup(0), "rb")
    chan_out = os.fdopen(os.dup(1), "wb")
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)

    def send(msg: dict) -> None:
        try:
            line = dumps(msg)
        except WireError as err:
            line = dumps({"ok": False, "unencodable": True, "error": str(err)})
        chan_out.write(line)
        chan_out.flush()

    name = os.path.splitext(os.path.basename(filename))[0]
    try:
        spec = importlib.util.spec_from_file_location(name, filename)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    except BaseException as err:  # noqa: BLE001 - report everything, including SystemExit
        reply = _error(err, filename)
        if reply["type"] == "SystemExit":
            reply["error"] = f"importing {os.path.basename(filename)}: {reply['error']}"
        send({"ready": False, "error": reply["error"]})
        return
    send({"ready": True})

    def make_problem(spec: dict) -> object:
        # imported only when a test hands a problem over: a sandbox of an exercise whose tests
        # never do has no problems.py (its spring forces are exercise 01's answer)
        from problems import Problem

        return Problem(spec["name"], **spec["params"])

    for line in chan_in:
        try:
            req = loads(line, make_problem)
            op, attr = req["op"], req["name"]
            if op == "getattr":
                value = getattr(module, attr)
                if callable(value):
                    send({"ok": True, "callable": True})
                else:
                    send({"ok": True, "callable": False, "value": value})
            elif op == "call":
                func = getattr(module, attr)
                send({"ok": True, "value": func(*req["args"], **req["kwargs"])})
            else:
                send({"ok": False, "type": "WireError", "mro": ["WireError"], "error": "unknown op"})
        except BaseException as err:  # noqa: BLE001 - the student's error is the answer
            send(_error(err, filename))


if __name__ == "__main__":
    main()
