# %% [markdown]
# # Two-mode nanostring: identification from multi-tone spectra
#
# The method's two-mode example (Wattjes et al. 2026): two Duffing modes of a Si3N4 nanostring,
# coupled dispersively, identified from three measurements (two tones near each resonance, then
# both pairs with a third tone on mode 2). Run from the repository root:
#
#     python python/examples/two_mode.py [--plot FILE.png]
#
# Each `# %%` cell runs as a notebook cell in Jupyter or VS Code.

# %%
import argparse
import sys
from pathlib import Path

import harmonid

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "nanostring_2mode"

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--plot", default="two_mode_identification.png", help="where to save the figure")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)

# %% The model and its equations of motion
model = harmonid.Model.from_file(EXAMPLE / "model.hb")
print(model)
for mode, terms in model.equations().items():
    print(f"  equation of {mode}: " + " + ".join(f"{list(c)[0]}·{m}" for m, c in terms.items()))

# %% Which lines does each term put near the resonances? (Table S1 of the paper)
lines = harmonid.mix(model, {"q1": [207572.5, 207592.5], "q2": [415841.5]})
try:
    import pandas as pd

    table = pd.DataFrame(lines)
    near = table[table.near.notna()][["equation", "monomial", "combination", "freq_hz", "near"]]
    print(f"\n{len(table)} lines, {len(near)} near a resonance; the first near q1:")
    print(near[near.near == "q1"].head(8).to_string(index=False))
except ImportError:
    print(f"\n{len(lines)} lines (install pandas for the table)")

# %% The measured dataset and the identification
data = harmonid.Dataset.from_folder(EXAMPLE / "data")
print(f"\n{data}")
result = harmonid.identify(model, data)
print(result.summary())

# The dataset was simulated, so its truth.toml lists the true coefficient of every monomial.
print("coefficient         identified        true")
for mode, coeffs in result.eom.items():
    for mono, value in coeffs.items():
        true = data.truth["eom"][mode][mono]
        print(f"{mode}: {mono:<9} {value:14.4e} {true:14.4e}   ({value / true - 1:+.1%})")

# %% The same experiment, simulated: the shipped data were made this way (values.toml, plan.toml)
again = harmonid.simulate(model, EXAMPLE / "values.toml", EXAMPLE / "plan.toml")
again_result = harmonid.identify(model, again)
g_ship, g_again = (r.parameters["g12"]["value"] for r in (result, again_result))
print(f"\nsimulated again from values.toml and plan.toml: g12 = {g_again:.6e}"
      f" (shipped data: {g_ship:.6e}, relative difference {abs(g_again / g_ship - 1):.1e})")

# %% How good could the experiment be? The Cramér–Rao bounds of the shipped plan (docs/planning.md)
score = harmonid.evaluate_plan(model, EXAMPLE / "values.toml", EXAMPLE / "plan.toml", 0.05e-9, 20)
print("\nplan.toml at 0.05 nm per quadrature, 20 shots (harmonid plan --evaluate):")
print(score.table(), end="")
for name in ("beta1", "beta2", "g12"):
    bound = score.quantities[name]
    print(f"  {name}: relative bound {bound['rel']:.3f}; the identification's stderr"
          f" {result.parameters[name]['stderr'] / abs(result.parameters[name]['value']):.3f}")

# %% Per-shot estimates: the histograms of the method's paper
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("\nmatplotlib is not installed: skipping the plot (pip install matplotlib)")
else:
    cols = ["f_hz:q1", "Q:q1", "beta1", "beta2", "g12"]
    fig, axes = plt.subplots(1, len(cols), figsize=(3.2 * len(cols), 3))
    ok = ~result.per_shot["outlier"]
    for ax, col in zip(axes, cols):
        values = result.per_shot[col][ok]
        ax.hist(values, bins=10, color="tab:blue", alpha=0.8)
        group, _, key = col.partition(":")
        est = result.modes[key][group] if key else result.parameters[col]
        ax.axvline(est["value"], color="k", lw=1, label="median")
        ax.set_title(col)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 3))
    axes[0].legend()
    fig.suptitle(f"{len(ok)} shots, per-shot estimates")
    fig.tight_layout()
    fig.savefig(args.plot, dpi=120)
    print(f"\nwrote {args.plot}")
