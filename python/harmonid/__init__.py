"""harmonid: identify nonlinear multimode resonator models from multi-tone sideband spectra.

Every mode ``n`` obeys (mass-normalised, SI units, per kg of modal mass)::

    q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q) = Σ_d F_d^(n) cos(2π f_d t + φ_d^(n))

and a complex amplitude ``X`` at frequency ``f`` means ``Re[X e^{i2πft}]`` (peak amplitude).

Quick start::

    import harmonid
    model = harmonid.Model.from_file("examples/nanostring_2mode/model.hb")
    data = harmonid.Dataset.from_folder("examples/nanostring_2mode/data")
    result = harmonid.identify(model, data)
    print(result.summary())
    result.parameters["g12"]          # {"value": ..., "std": ..., "stderr": ...}
    result.per_shot["g12"]            # numpy array, one estimate per shot

The work is done by the compiled Rust library (the same code as the ``harmonid`` command);
long computations release the GIL.
"""

from collections.abc import Mapping

from . import _harmonid
from ._harmonid import (
    Dataset,
    DatasetError,
    HarmonidError,
    IdentifyError,
    IdentifyResult,
    Model,
    ModelError,
    PlanError,
    PlanResult,
    SimulationError,
    discover,
    evaluate_plan,
    identify,
    plan,
    simulate,
    sweep,
    response,
    linear_response,
    states,
    phase_diagram,
)

from . import io  # noqa: E402  (after _harmonid, which it re-exports)

__version__ = _harmonid.__version__

__all__ = [
    "Dataset",
    "DatasetError",
    "HarmonidError",
    "IdentifyError",
    "IdentifyResult",
    "Model",
    "ModelError",
    "PlanError",
    "PlanResult",
    "SimulationError",
    "compare",
    "discover",
    "evaluate_plan",
    "identify",
    "io",
    "mix",
    "plan",
    "simulate",
    "sweep",
    "response",
    "linear_response",
    "states",
    "phase_diagram",
]


def mix(model, drives, *, sidebands=None, window_hz=None, nominal_hz=None):
    """The lines every term of every equation generates under a set of tones.

    ``drives`` maps each mode to the tones in its motion, in Hz:
    ``{"q1": [207572, 207592], "q2": [415842]}`` (or a list of ``(mode, [Hz, ...])`` pairs).
    Tones are numbered f1, f2, ... in the order given; a component's real amplitude is the
    symbol X1, X2, ... ``sidebands`` lets every mode with two or more tones carry its own
    sidebands up to that intermodulation order (amplitudes Y1, Y2, ...). A line is "near" a
    resonance within ``window_hz`` of it (default: 1 % of the resonance frequency);
    ``nominal_hz`` overrides the model's nominal resonances.

    Returns one record (dict) per line, as ``harmonid mix --json`` lists them: ``equation``,
    ``monomial``, ``term_coefficient``, ``combination``, ``coeffs``, ``freq_hz``,
    ``coefficient`` (the amplitude of ``cos(2π f t)`` in the monomial), ``near``,
    ``second_order`` and ``via``: a mode without a tone responds through the coupling at the
    lines its equation's terms force on it (amplitudes Z1, Z2, ...), and a line that goes
    through such a response is second order, ``via`` naming those modes.
    ``pandas.DataFrame(mix(...))`` is the table.
    """
    if isinstance(drives, Mapping):
        drives = list(drives.items())
    pairs = [(str(mode), [float(f) for f in tones]) for mode, tones in drives]
    return _harmonid.mix(
        model, pairs, sidebands=sidebands, window_hz=window_hz, nominal_hz=nominal_hz
    )



def compare(dataset, models, *, force_model="auto", holdout=(), error_floor=False,
            background=None):
    """Fits ``dataset`` by every model and says which one the data support.

    ``models`` maps a name to each ``Model`` (or is a list of ``(name, Model)`` pairs). Returns
    the dict ``harmonid compare DATASET MODEL... --json`` prints: ``observations``, ``models``
    (per model ``unknowns``, ``chi2``, ``chi2_per_dof``, ``fits``, ``p_value``,
    ``log_likelihood``, ``aic``, ``bic``, ``delta_aic``, ``delta_bic``, and with ``holdout``
    ``holdout_relative_rms`` and ``holdout_rms_sigma``), ``nested`` (likelihood-ratio tests of
    nested pairs), ``best``, ``ranked_by`` and ``verdict``. ``holdout`` (names of measurements
    or sweeps) fits every model without them and reports how well each predicts them;
    ``error_floor=True`` adds a fitted error floor to every model's noise and ranks the models
    by that prediction (``holdout`` is then required); ``background`` (``"drive"``,
    ``"slope"``, ``"constant"``, joined by commas) fits a measurement background with every
    model, as ``--background``.
    """
    if isinstance(models, Mapping):
        models = list(models.items())
    return _harmonid.compare(
        dataset,
        [(str(n), m) for n, m in models],
        force_model=force_model,
        holdout=[str(h) for h in holdout],
        error_floor=bool(error_floor),
        background=background,
    )
