"""Python overhead on a five-mode identification: `import harmonid`, then model, dataset and
`identify` in Python, against the `harmonid identify` process on the same data.

    python python/bench/identify_5mode.py [--repeat 5] [--estimator linear|ml]

Run from the repository root after `cargo build --release` (the command line) and with the
extension importable (`pip install ./python`, or PYTHONPATH=python after `.ci/run`'s build).
The dataset is made once by `harmonid simulate` in a temporary folder: the five-mode nanostring
(examples/nanostring_5mode/model.hb) with the values and drive plan of the round-trip tests
(crates/testgen/src/lib.rs `nanostring_5mode_plan`: a tone pair 5.5 linewidths either side
of each resonance, then every pair of modes together with a third tone; 15 measurements), 20
shots of 0.05 nm per quadrature. Times are medians over `--repeat` runs of CPU time (user +
system, all threads; the machine is shared, so wall-clock times wander) and wall-clock time;
nothing here asserts a time (the numbers go in python/README.md with the machine).
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MODEL = REPO / "examples/nanostring_5mode/model.hb"
CLI = Path(os.environ.get("HARMONID_CLI", REPO / "target/release/harmonid"))


def values_and_plan():
    """The values TOML and the plan TOML of `nanostring_5mode_plan`."""
    f1, beta1 = 207582.0, 2.68e22
    f = [k * f1 for k in (1.0, 2.0033, 3.0075, 4.0139, 5.0226)]
    q = [116232.0, 99173.0, 87000.0, 76000.0, 65000.0]
    params = {f"beta{n}": beta1 * n**4 for n in range(1, 6)}
    for n in range(1, 6):
        for m in range(n + 1, 6):
            params[f"g{n}{m}"] = 3.2 * beta1 * (n * n * m * m) / 3.0 * 0.25
    values = "".join(f"[modes.q{n + 1}]\nf_hz = {f[n]!r}\nQ = {q[n]!r}\n" for n in range(5))
    values += "[parameters]\n" + "".join(f"{k} = {v!r}\n" for k, v in params.items())

    force, detune = 3.5, 5.5
    plan = ['description = "five-mode nanostring, the round-trip tests\' plan"',
            "[noise]", "sigma_per_quadrature = 5e-11", "shots = 20"]

    def measurement(name, tones):
        modes = sorted({m for _, m, _ in tones})
        lines = [f"[[measurement]]", f'name = "{name}"',
                 f"drives_hz = [{', '.join(repr(t[0]) for t in tones)}]",
                 f"drive_levels_v = [{', '.join(repr(t[2]) for t in tones)}]",
                 f"drive_phases_rad = [{', '.join('0.0' for _ in tones)}]",
                 "[measurement.force]"]
        for m in modes:
            row = [repr(t[2]) if t[1] == m else "0.0" for t in tones]
            lines.append(f"q{m + 1} = [{', '.join(row)}]")
        return lines

    for n in range(5):
        d = detune * f[n] / q[n]
        plan += measurement(f"single_q{n + 1}", [(f[n] - d, n, force), (f[n] + d, n, force)])
    for n in range(5):
        for m in range(n + 1, 5):
            d, e = detune * f[n] / q[n], 0.5 * detune * f[m] / q[m]
            plan += measurement(f"couple_q{n + 1}_q{m + 1}",
                                [(f[n] - d, n, force), (f[n] + d, n, force),
                                 (f[m] + e, m, 0.5 * force)])
    return values, "\n".join(plan) + "\n"


def cpu_now():
    """CPU time (user + system) of this process and of its finished children, s."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def timed(fn, repeat):
    """Median CPU and wall-clock times of `repeat` calls, s (CPU: the machine may be shared)."""
    cpu, wall = [], []
    for _ in range(repeat):
        c, t = cpu_now(), time.perf_counter()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(cpu_now() - c)
    return statistics.median(cpu), statistics.median(wall)


def ms(pair):
    return f"CPU {1e3 * pair[0]:7.1f} ms, wall {1e3 * pair[1]:7.1f} ms"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--estimator", choices=["ml", "linear"], default="linear")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="harmonid-bench-"))
    values, plan = values_and_plan()
    (tmp / "values.toml").write_text(values)
    (tmp / "plan.toml").write_text(plan)
    data = tmp / "data"
    subprocess.run([str(CLI), "simulate", str(MODEL), "--values", str(tmp / "values.toml"),
                    "--plan", str(tmp / "plan.toml"), "--out", str(data)],
                   check=True, capture_output=True)

    flags = ["--estimator", args.estimator]
    cli = timed(lambda: subprocess.run([str(CLI), "identify", str(MODEL), str(data), *flags],
                                      check=True, capture_output=True), args.repeat)
    # A fresh interpreter: start-up, import, load and identify (the whole Python job).
    env = dict(os.environ)
    code = ("import harmonid\n"
            f"harmonid.identify(harmonid.Model.from_file({str(MODEL)!r}),"
            f" harmonid.Dataset.from_folder({str(data)!r}), estimator={args.estimator!r})\n")
    fresh = timed(lambda: subprocess.run([sys.executable, "-c", code], check=True, env=env),
                 args.repeat)
    bare = timed(lambda: subprocess.run([sys.executable, "-c", "pass"], check=True), args.repeat)
    imp = timed(lambda: subprocess.run([sys.executable, "-c", "import harmonid"], check=True,
                                      env=env), args.repeat)

    import harmonid

    def in_process():
        harmonid.identify(harmonid.Model.from_file(MODEL), harmonid.Dataset.from_folder(data),
                          estimator=args.estimator)

    inproc = timed(in_process, args.repeat)
    ds = harmonid.Dataset.from_folder(data)
    n_meas = len(ds.measurements)
    shots = ds.measurement(ds.measurements[0])["amplitudes"].shape[0]
    print(f"five-mode nanostring, {n_meas} measurements, {shots} shots, estimator {args.estimator},"
          f" {os.cpu_count()} cores, median of {args.repeat}")
    print(f"harmonid identify (whole process)          {ms(cli)}")
    print(f"python: load + identify, in process         {ms(inproc)}")
    print(f"python -c '' (interpreter start-up)        {ms(bare)}")
    print(f"python -c 'import harmonid'                {ms(imp)}"
          f" (import: CPU {1e3 * (imp[0] - bare[0]):.1f} ms)")
    print(f"python -c: import + load + identify        {ms(fresh)}")
    print(f"beyond the command line, start-up excluded: CPU {1e3 * (fresh[0] - bare[0] - cli[0]):+.1f} ms,"
          f" wall {1e3 * (fresh[1] - bare[1] - cli[1]):+.1f} ms;"
          f" in process: CPU {1e3 * (inproc[0] - cli[0]):+.1f} ms")


if __name__ == "__main__":
    main()
