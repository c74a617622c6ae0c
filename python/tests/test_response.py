"""response: the data of the report's frequency-response figure, as numpy arrays."""

import numpy as np

import harmonid

MODEL = """
mode q1 at 1 kHz
param beta1
potential: beta1/4*q1^4
"""
VALUES = {"modes": {"q1": {"f_hz": 1000.0, "Q": 200.0}}, "parameters": {"beta1": 2e12}}
LEVEL = 20.0  # N/kg (the drive level is the force: gain 1)


def sweep_dataset():
    """An up-sweep of 27 steps through the resonance from the model's own curve, 5 shots a
    step with 0.1 % noise."""
    model = harmonid.Model.from_str(MODEL)
    curve = harmonid.sweep(model, VALUES, 990.0, 1010.0, {"q1": LEVEL}, points=400, harmonics=1)
    f, x = curve["f_hz"], curve["amplitudes"][:, 0, 0]
    assert np.all(np.diff(f) > 0), "a curve without folds"
    rng = np.random.default_rng(5)
    steps = []
    for i in range(0, len(f), max(1, len(f) // 27)):
        noise = 1e-3 * abs(x[i]) * (rng.standard_normal(5) + 1j * rng.standard_normal(5))
        steps.append(
            {
                "drives_hz": [f[i]],
                "freqs_hz": [f[i]],
                "amplitudes": (x[i] + noise).reshape(5, 1),
                "drive_levels_v": [LEVEL],
                "drive_phases_rad": [0.0],
            }
        )
    ds = harmonid.Dataset.from_arrays({}, sweeps=[{"name": "up", "steps": steps}])
    return model, ds, steps


def test_response_of_a_sweep():
    model, ds, steps = sweep_dataset()
    result = harmonid.identify(model, ds, force_model="gain_per_mode")
    r = harmonid.response(model, result, ds, "up")
    assert r["unit"] == "m" and r["family"] == "level 20" and r["level"] == LEVEL
    (s,) = r["sweeps"]
    assert s["name"] == "up" and s["direction"] == "up" and len(s["steps"]) == len(steps)
    np.testing.assert_allclose(s["f_hz"], [st["drives_hz"][0] for st in steps], rtol=1e-12)
    # The measured amplitude is the median over the shots; the model at each step meets it to
    # the noise, and its phase runs from 0 below the resonance to -pi above it.
    med = [np.median(st["amplitudes"].real) + 1j * np.median(st["amplitudes"].imag) for st in steps]
    np.testing.assert_allclose(s["amplitude"], np.abs(med), rtol=1e-9)
    np.testing.assert_allclose(s["model_amplitude"], s["amplitude"], rtol=5e-3)
    assert abs(s["phase_rad"][0]) < 0.3 and abs(s["phase_rad"][-1] + np.pi) < 0.3
    m = r["model"]
    assert m["stable"].all() and m["harmonics"] == 1
    assert abs(abs(m["force"][0]) - LEVEL) < 1e-2 * LEVEL
    assert abs(m["amplitude"].max() - s["amplitude"].max()) < 2e-2 * s["amplitude"].max()
    # The curve passes through the measured points (interpolated in frequency).
    on_curve = np.interp(s["f_hz"], m["f_hz"], m["amplitude"])
    np.testing.assert_allclose(on_curve, s["amplitude"], rtol=1e-2)


def test_unknown_sweep_is_an_error():
    model, ds, _ = sweep_dataset()
    result = harmonid.identify(model, ds, force_model="gain_per_mode")
    try:
        harmonid.response(model, result, ds, "down")
    except harmonid.DatasetError as e:
        assert "up" in str(e)
    else:
        raise AssertionError("no error for an unknown sweep")
