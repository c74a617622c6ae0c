#!/usr/bin/env python3
"""harmonid vs scipy's odeint: the time-domain simulation of one measurement (single_q1 of the
two-mode nanostring model, Table S2 values, 3.5 N/kg per tone at 207572.5 and 207592.5 Hz), the
route of the paper's Supplementary Note V: integrate the equations of motion, then take the DFT
of the last window at the measured frequencies.

Both sides start from the same harmonic-balance state, integrate the same simulated time (one
decay time 2Q/w of the slowest mode to settle, then one lock-in window holding whole periods of
every frequency) and are compared with the harmonic-balance amplitudes (equal accuracy).
Run by hand (not in CI), from the workspace root, after `cargo build --release`:

    pip install scipy numpy
    python3 benches/scipy_compare.py [--fraction 0.1] [--rtol 1e-10] [--scan 8,10,12,16]

--scan also runs harmonid at each listed --steps-per-period (optionally with its --rtol, as
SPP:RTOL) and reports the ratio at equal accuracy: the fastest setting whose error vs HB is at
most odeint's (a setting below what the error control accepts is refined automatically, so the
coarsest one is not always the fastest). harmonid's times are the best of --repeat runs.

--fraction F integrates only the first F of the settling time with odeint and extrapolates the
time linearly (the accuracy is then that of the shortened run and is reported as such).
"""

import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.integrate import odeint

F1, Q1, F2, Q2 = 207582.0, 116232.0, 415842.0, 599173.0
BETA1, BETA2, G12 = 2.68e22, 3.70e23, 8.57e22
TONES = [207572.5, 207592.5]
FORCE = 3.5  # N/kg per tone on mode 1
MEASURE = [207492.5 + 20.0 * k for k in range(10)]

VALUES = f"""
[modes.q1]
f_hz = {F1}
Q = {Q1}
[modes.q2]
f_hz = {F2}
Q = {Q2}
[parameters]
beta1 = {BETA1}
beta2 = {BETA2}
g12 = {G12}
"""

PLAN = f"""
displacement_unit = "m"
[[point]]
name = "q1"
shape = {{ q1 = 1.0, q2 = 0.0 }}
[[point]]
name = "q2"
shape = {{ q1 = 0.0, q2 = 1.0 }}
[[measurement]]
name = "single_q1"
drives_hz = {TONES}
force = {{ q1 = [{FORCE}, {FORCE}] }}
measure_hz = {MEASURE}
"""


def read_dataset(path):
    """{point: {freq: complex}} of shot 0 of single_q1.csv."""
    out = {}
    with open(os.path.join(path, "single_q1.csv")) as f:
        for row in csv.DictReader(f):
            if int(row["shot"]) != 0:
                continue
            p = row.get("point", "q1")
            out.setdefault(p, {})[float(row["freq_hz"])] = complex(float(row["re"]), float(row["im"]))
    return out


def harmonid(exe, tmp, time_domain, spp=32, rtol=None, repeat=1):
    """Runs `harmonid simulate`; the time is the best of `repeat` runs (the least disturbed)."""
    out = os.path.join(tmp, "td" if time_domain else "hb")
    cmd = [exe, "simulate", "examples/nanostring_2mode/model.hb", "--values",
           os.path.join(tmp, "values.toml"), "--plan", os.path.join(tmp, "plan.toml"), "--out", out]
    if time_domain:
        cmd += ["--time-domain", "--steps-per-period", str(spp)]
        if rtol is not None:
            cmd += ["--rtol", str(rtol)]
    best = float("inf")
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t0)
        if r.returncode != 0:
            sys.exit(f"harmonid failed: {r.stderr}")
    return read_dataset(out), best, r.stderr


def rel_error(got, ref):
    """max |got - ref| / |ref| over the components above 1 % of the largest."""
    big = max(abs(z) for z in ref.values())
    return max(abs(got[f] - z) / abs(z) for f, z in ref.items() if abs(z) > 0.01 * big)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--exe", default="target/release/harmonid")
    ap.add_argument("--fraction", type=float, default=1.0)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--steps-per-period", type=int, default=16,
                    help="harmonid's integration steps per period of the highest frequency")
    ap.add_argument("--scan", default="",
                    help="comma-separated harmonid settings to time for the equal-accuracy ratio: "
                         "steps per period, optionally with harmonid's --rtol as SPP:RTOL (6:1e-7)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="harmonid runs per setting; the best time counts")
    args = ap.parse_args()

    tmp = tempfile.mkdtemp()
    open(os.path.join(tmp, "values.toml"), "w").write(VALUES)
    open(os.path.join(tmp, "plan.toml"), "w").write(PLAN)
    hb, t_hb, _ = harmonid(args.exe, tmp, False)
    td, t_td, log = harmonid(args.exe, tmp, True, args.steps_per_period, repeat=args.repeat)
    err_td = rel_error(td["q1"], hb["q1"])
    scan = []
    for item in [x.strip() for x in args.scan.split(",") if x.strip()]:
        spp, _, rtol = item.partition(":")
        rtol = float(rtol) if rtol else None
        d, t, lg = harmonid(args.exe, tmp, True, int(spp), rtol, args.repeat)
        scan.append((item, t, rel_error(d["q1"], hb["q1"]), lg))

    # Same start state: the HB amplitudes at t = 0 (the HB lattice of single_q1 is the measured
    # frequencies).
    w1, w2 = 2 * math.pi * F1, 2 * math.pi * F2
    g1, g2 = w1 / Q1, w2 / Q2
    scale = 1e9  # integrate in nm for well-scaled tolerances
    y0 = []
    for p in ["q1", "q2"]:
        q = sum(z.real for z in hb[p].values())
        v = sum(-2 * math.pi * f * z.imag for f, z in hb[p].items())
        y0 += [q * scale, v * scale]
    om = [2 * math.pi * f for f in TONES]
    b1, b2, c12 = BETA1 / scale**2, BETA2 / scale**2, G12 / scale**2
    fsc = FORCE * scale

    def rhs(y, t):
        q1, v1, q2, v2 = y
        f = fsc * (math.cos(om[0] * t) + math.cos(om[1] * t))
        a1 = f - g1 * v1 - w1 * w1 * q1 - b1 * q1**3 - c12 * q1 * q2 * q2
        a2 = -g2 * v2 - w2 * w2 * q2 - b2 * q2**3 - c12 * q1 * q1 * q2
        return [v1, a1, v2, a2]

    # Settling (one decay time of the slowest mode, as harmonid from a given state) and one
    # window of whole periods of every frequency (grid 2.5 Hz -> 0.4 s).
    settle = max(2 * Q1 / w1, 2 * Q2 / w2)
    window = 0.4
    fs = 8 * max(MEASURE)
    n = int(round(window * fs))
    atol = [1e-9, 1e-9 * w1, 1e-9, 1e-9 * w2]
    t_settle = settle * args.fraction
    t0 = time.perf_counter()
    ys = odeint(rhs, y0, [0.0, t_settle], rtol=args.rtol, atol=atol, mxstep=10**9)
    t_mid = time.perf_counter() - t0
    tw = t_settle + np.arange(n + 1) / fs
    t1 = time.perf_counter()
    yw = odeint(rhs, ys[-1], tw, rtol=args.rtol, atol=atol, mxstep=10**9)
    t_win = time.perf_counter() - t1
    t_scipy = t_mid / max(args.fraction, 1e-12) + t_win
    x = yw[:-1, 0] / scale
    tt = tw[:-1]
    dft = {f: 2.0 / n * np.sum(x * np.exp(-2j * math.pi * f * tt)) for f in MEASURE}
    err_py = rel_error(dft, hb["q1"])

    print(f"harmonid HB (process, incl. start-up):          {t_hb * 1e3:9.1f} ms")
    print(f"harmonid time domain (process, incl. HB start): {t_td * 1e3:9.1f} ms, max rel. error vs HB {err_td:.1e}")
    print("   " + " | ".join(l for l in log.splitlines() if "time domain" in l))
    what = "" if args.fraction >= 1.0 else f" (settling integrated over {args.fraction:g} of it and extrapolated)"
    print(f"scipy odeint (rtol {args.rtol:g}):                 {t_scipy * 1e3:9.1f} ms{what}, max rel. error vs HB {err_py:.1e}")
    print(f"   odeint: settling {t_mid:.2f} s for {t_settle:.4f} s simulated, window {t_win:.2f} s for {window} s simulated")
    print(f"ratio scipy / harmonid time domain: {t_scipy / t_td:.0f}x")
    for spp, t, e, lg in scan:
        used = " | ".join(l for l in lg.splitlines() if "time domain" in l)
        print(f"harmonid {spp:>10}: {t * 1e3:9.1f} ms, max rel. error vs HB {e:.1e}   {used}")
    ok = [(spp, t, e) for spp, t, e, _ in scan if e <= err_py]
    if ok:
        spp, t, e = min(ok, key=lambda r: r[1])
        print(f"equal accuracy: fastest harmonid setting with error <= odeint's ({err_py:.1e}) is "
              f"{spp} (steps/period[:rtol]; {e:.1e}, {t * 1e3:.1f} ms): ratio {t_scipy / t:.0f}x")
    elif scan:
        print(f"equal accuracy: no scanned setting reaches odeint's error {err_py:.1e}")


if __name__ == "__main__":
    main()
