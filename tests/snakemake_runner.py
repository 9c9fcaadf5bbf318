"""`snakemake <args>` for the workflow tests without paying Snakemake's import at every call.

Each `snakemake` command spends about as much CPU importing Snakemake (~1.5 s) as a dry run of the workflow takes,
and the workflow tests run some thirty of them. One server process per test process imports Snakemake (and the
vesicle_core modules the Snakefile imports) once, then forks a child for every call: the child is a fresh process
(a copy of the server, which has run nothing yet) that changes to the workflow copy, takes the call's environment,
writes to its own stdout/stderr files and runs Snakemake's command-line entry point (`snakemake.cli:main`, what the
`snakemake` script runs). The result is a subprocess.CompletedProcess as from subprocess.run, and a call that
outlives its timeout is killed with its process group and raises subprocess.TimeoutExpired.
"""

import atexit
import json
import subprocess
import sys
import tempfile
from pathlib import Path

#: the server: one JSON request per line on stdin, one JSON reply per line on stdout
_SERVER = r"""
import json, os, signal, sys, time, traceback

import snakemake.cli
import vesicle_core.data.case_ids, vesicle_core.model.parameters, vesicle_core.model.units  # the Snakefile's imports

for line in sys.stdin:
    req = json.loads(line)
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.setpgrp()  # a timeout kills the call with every job it started
            null = os.open(os.devnull, os.O_RDONLY)
            os.dup2(null, 0)  # the child never reads the requests
            for fd, path in ((1, req["stdout"]), (2, req["stderr"])):
                os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
            os.chdir(req["cwd"])
            os.environ.clear()
            os.environ.update(req["env"])
            sys.argv = [req["argv0"], *req["args"]]
            snakemake.cli.main(req["args"])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:
            traceback.print_exc()
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
    deadline = time.monotonic() + req["timeout"]
    timed_out = False
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            timed_out, status = True, -9
            break
        time.sleep(0.02)
    rc = os.waitstatus_to_exitcode(status) if not timed_out else -9
    sys.stdout.write(json.dumps({"rc": rc, "timed_out": timed_out}) + "\n")
    sys.stdout.flush()
"""

_server = None


def _stop():
    if _server is not None and _server.poll() is None:
        _server.stdin.close()
        _server.wait(timeout=10)


def _get_server(env):
    global _server
    if _server is None or _server.poll() is not None:
        _server = subprocess.Popen([sys.executable, "-c", _SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                   env=env, text=True)
        atexit.register(_stop)
    return _server


def run_snakemake(wd, args, env, timeout=300):
    """`snakemake *args` in ``wd`` with environment ``env``; a CompletedProcess with text stdout and stderr."""
    server = _get_server(env)
    with tempfile.TemporaryDirectory(prefix="snakemake-call-") as tmp:
        out, err = Path(tmp) / "stdout", Path(tmp) / "stderr"
        req = {"cwd": str(wd), "args": [str(a) for a in args], "env": env, "timeout": timeout,
               "argv0": str(Path(sys.executable).parent / "snakemake"), "stdout": str(out), "stderr": str(err)}
        server.stdin.write(json.dumps(req) + "\n")
        server.stdin.flush()
        reply = server.stdout.readline()
        if not reply:
            raise RuntimeError(f"the snakemake server exited (status {server.wait()})")
        reply = json.loads(reply)
        stdout, stderr = out.read_text(errors="replace"), err.read_text(errors="replace")
    cmd = ["snakemake", *map(str, args)]
    if reply["timed_out"]:
        raise subprocess.TimeoutExpired(cmd, timeout, output=stdout, stderr=stderr)
    return subprocess.CompletedProcess(cmd, reply["rc"], stdout, stderr)
