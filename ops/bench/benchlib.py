"""What every benchmark script here shares: finding the binary, running a command with a clear
error, timing it, the statistics the tables print, and keeping results as data.

A script imports it as `import benchlib` (this folder is the script's own, so it is on
`sys.path` already); the VAE's benchmarks in `vae/bench/` put this folder on the path first.
Standard library only.

Results are data: `Results("thread_scaling", args.record)` appends JSON lines to
`ops/bench/runs/<date>-<machine>/thread_scaling.jsonl` and writes that folder's
`machine.json` (CPU, cores, memory, commit, binary version) once, so a figure in the docs can
name the file it came from. `--record` is off unless asked for (`add_record_argument`);
$SPARC3D_BENCH_RUNS puts the runs folder elsewhere.
"""

import json
import os
import pathlib
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
RUNS = pathlib.Path(os.environ.get("SPARC3D_BENCH_RUNS") or HERE / "runs")
MESH_EXTENSIONS = {".obj", ".ply", ".stl", ".off", ".gltf", ".glb"}
"""The file suffixes a benchmark takes for meshes in a folder."""


def fail(msg):
    """Ends the script with `error: MSG` on stderr and exit status 2."""
    print(f"error: {msg}", file=sys.stderr)
    sys.exit(2)


def binary(given=None):
    """The `sparc3d` binary to measure: `given` (a `--bin`), else $SPARC3D_BIN, else the
    checkout's release build, else `sparc3d` on PATH; ends the script when there is none."""
    for source, candidate in (("--bin", given), ("SPARC3D_BIN", os.environ.get("SPARC3D_BIN"))):
        if candidate:
            if pathlib.Path(candidate).is_file() or shutil.which(candidate):
                return candidate
            fail(f"{source} {candidate}: no such program")
    if (ROOT / "target/release/sparc3d").is_file():
        return str(ROOT / "target/release/sparc3d")
    found = shutil.which("sparc3d")
    if found:
        return found
    fail("no sparc3d binary: pass --bin, set SPARC3D_BIN or build with cargo build --release")


def add_binary_argument(parser):
    """`--bin PATH`, resolved later with `binary(args.bin)`."""
    parser.add_argument("--bin", help="the sparc3d binary (default: $SPARC3D_BIN, "
                        "target/release/sparc3d, then PATH)")


def add_record_argument(parser):
    """`--record [MACHINE]`: keep the results under runs/<date>-<machine>/."""
    parser.add_argument("--record", nargs="?", const=default_machine(), metavar="MACHINE",
                        help="keep the results as data in ops/bench/runs/<date>-MACHINE/ "
                        f"(MACHINE default: {default_machine()})")


def command_line(cmd):
    """`cmd` as one printable line."""
    return " ".join(map(str, cmd))


def run(cmd, timeout=None, env=None, quiet=True):
    """Runs `cmd` and returns its CompletedProcess (text, output captured when `quiet`);
    ends the script with the command and its stderr's tail when it fails."""
    cmd = [str(c) for c in cmd]
    try:
        r = subprocess.run(cmd, text=True, capture_output=quiet, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        fail(f"{command_line(cmd)}: no answer in {timeout} s")
    except OSError as e:
        fail(f"{command_line(cmd)}: {e}")
    if r.returncode != 0:
        tail = (r.stderr or "").strip()[-2000:]
        fail(f"{command_line(cmd)} exited {r.returncode}: {tail}")
    return r


def last_json(cmd, timeout=None, json_optional=False):
    """Runs a command that prints a JSON object on a stdout line of its own, the last such
    line taken: (object or None, seconds, error or None). A failure is returned, not raised,
    so that a benchmark over many items records it and goes on. With `json_optional`, a run
    that succeeds and prints no object gives `{}`."""
    start = time.monotonic()
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, time.monotonic() - start, f"timeout after {timeout:.0f}s"
    seconds = time.monotonic() - start
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        return None, seconds, f"exit {proc.returncode}: {' | '.join(tail)}"
    lines = [line for line in proc.stdout.splitlines() if line.lstrip().startswith("{")]
    if json_optional and not lines:
        return {}, seconds, None
    try:
        return json.loads(lines[-1]), seconds, None
    except (IndexError, json.JSONDecodeError) as e:
        return None, seconds, f"no JSON on stdout ({e})"


def peak_kb(pid):
    """The peak resident set of a running process (VmHWM), in KB; 0 when it cannot be read."""
    try:
        with open(f"/proc/{pid}/status", encoding="utf-8") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def timed(cmd, until=None, env=None):
    """Runs `cmd`: (seconds to its end, or to the first stdout line holding `until`, when it
    is stopped), (seconds to its first stdout line, None without one), its peak resident set
    in KB (from wait4, or VmHWM when it was stopped); ends the script when it fails."""
    t0 = time.monotonic()
    try:
        p = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env)
    except OSError as e:
        fail(f"{command_line(cmd)}: {e}")
    first = None
    for line in p.stdout:
        if first is None:
            first = time.monotonic() - t0
        if until is not None and until in line:
            at = time.monotonic() - t0
            peak = peak_kb(p.pid)
            p.send_signal(signal.SIGTERM)
            p.communicate(timeout=60)
            return at, first, peak
    err = p.stderr.read()
    _, status, usage = os.wait4(p.pid, 0)
    seconds = time.monotonic() - t0
    code = os.waitstatus_to_exitcode(status)
    p.returncode = code
    if code != 0:
        fail(f"{command_line(cmd)} exited {code}: {err.strip()[-2000:]}")
    return seconds, first, usage.ru_maxrss


def median(values):
    """The median of `values`, None when there are none."""
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def percentile(values, q):
    """The `q`-th percentile (0–100, nearest rank) of `values`, None when there are none."""
    values = sorted(v for v in values if v is not None)
    if not values:
        return None
    return values[min(len(values) - 1, max(0, round(q / 100 * (len(values) - 1))))]


def default_machine():
    """A short name of this machine: `<cores>c-<cpu>`, e.g. `2c-amd-epyc`."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            model = next(line.split(":", 1)[1] for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    words = "".join(ch if ch.isalnum() else " " for ch in model.lower()).split()
    return f"{os.cpu_count()}c-" + "-".join(words[:3] or ["cpu"])


def machine_facts(sparc3d=None):
    """What a result depends on: CPU, cores, memory, OS, the checkout's commit and the
    binary's version."""
    facts = {"machine": default_machine(), "cores": os.cpu_count(),
             "platform": platform.platform(), "python": platform.python_version()}
    try:
        with open("/proc/meminfo", encoding="utf-8") as f:
            facts["memory_kb"] = int(f.readline().split()[1])
    except (OSError, ValueError, IndexError):
        pass
    facts["commit"] = _quiet_output(["git", "-C", str(ROOT), "rev-parse", "HEAD"])
    if sparc3d:
        facts["binary"] = _quiet_output([sparc3d, "--version"])
    return facts


def _quiet_output(cmd):
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


class Results:
    """Results of one benchmark kept as data: with `machine` set (a `--record`), each
    `add(row)` appends a JSON line to `runs/<date>-<machine>/<bench>.jsonl`; without it,
    `add` does nothing, so a script calls it unconditionally."""

    def __init__(self, bench, machine, sparc3d=None, runs=RUNS):
        self.path = None
        if not machine:
            return
        folder = pathlib.Path(runs) / f"{time.strftime('%Y-%m-%d')}-{machine}"
        folder.mkdir(parents=True, exist_ok=True)
        facts = folder / "machine.json"
        if not facts.exists():
            facts.write_text(json.dumps(machine_facts(sparc3d), indent=1) + "\n")
        self.path = folder / f"{bench}.jsonl"

    def add(self, row):
        """Appends `row` (a JSON object) when recording."""
        if self.path is not None:
            with open(self.path, "a", encoding="utf-8") as f:
                f.write(json.dumps(row, sort_keys=True) + "\n")


if __name__ == "__main__":
    # The shell scripts here ask for the binary the same way: `python3 benchlib.py binary [PATH]`.
    if len(sys.argv) in (2, 3) and sys.argv[1] == "binary":
        print(binary(sys.argv[2] if len(sys.argv) == 3 else None))
    else:
        fail("usage: benchlib.py binary [PATH]")
