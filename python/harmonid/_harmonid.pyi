"""Type stubs of the compiled module ``harmonid._harmonid`` (docstrings live on the objects)."""

import os
from collections.abc import Mapping, Sequence
from typing import Any, Literal, Optional, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, os.PathLike[str]]

class HarmonidError(ValueError): ...
class ModelError(HarmonidError): ...
class DatasetError(HarmonidError): ...
class IdentifyError(HarmonidError): ...
class SimulationError(HarmonidError): ...
class PlanError(HarmonidError): ...

class Model:
    @staticmethod
    def from_file(path: _Path) -> Model: ...
    @staticmethod
    def from_str(text: str, origin: str = "<string>") -> Model: ...
    @property
    def source(self) -> str: ...
    @property
    def modes(self) -> dict[str, dict[str, Optional[float]]]: ...
    @property
    def parameters(self) -> dict[str, dict[str, Any]]: ...
    @property
    def identifiable(self) -> bool: ...
    @overload
    def equations(self, format: Literal["dict"] = "dict") -> dict[str, dict[str, dict[str, float]]]: ...
    @overload
    def equations(self, format: Literal["latex", "text"]) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...

class Dataset:
    @staticmethod
    def from_folder(path: _Path) -> Dataset: ...
    @staticmethod
    def from_arrays(
        measurements: Union[Mapping[str, Mapping[str, Any]], Sequence[Mapping[str, Any]]],
        *,
        displacement_unit: str = "m",
        points: Optional[Mapping[str, Mapping[str, float]]] = None,
        nominal_hz: Optional[Mapping[str, float]] = None,
        description: str = "",
        sweeps: Optional[Sequence[Mapping[str, Any]]] = None,
    ) -> Dataset: ...
    @staticmethod
    def merge(datasets: Sequence[Dataset]) -> Dataset:
        """Pools datasets of one device into one (in memory; write it with `to_folder`).

        They must agree on displacement_unit, points and shapes, the modes of nominal_hz and
        import conventions (else `DatasetError` naming the file, key and both values); nominal
        frequencies may differ (each round's plan writes its guess): the last dataset's are kept
        if every line keeps its mode. A folder given twice is refused. A name in several
        datasets becomes `<folder>_<name>` in each; sweeps keep their steps; `truth` is kept when
        all describe the same device (every round's forces); `notes` says what was renamed or
        dropped.
        """
    def to_folder(self, path: _Path) -> None: ...
    @property
    def path(self) -> str: ...
    @property
    def notes(self) -> list[str]: ...
    @property
    def measurements(self) -> list[str]: ...
    def measurement(self, name: str) -> dict[str, Any]: ...
    @property
    def manifest(self) -> dict[str, Any]: ...
    @property
    def truth(self) -> Optional[dict[str, Any]]: ...

class IdentifyResult:
    def to_dict(self) -> dict[str, Any]: ...
    def to_json(self) -> str: ...
    @property
    def parameters(self) -> dict[str, dict[str, Any]]: ...
    @property
    def modes(self) -> dict[str, dict[str, dict[str, Any]]]: ...
    @property
    def eom(self) -> dict[str, dict[str, Optional[float]]]: ...
    @property
    def goodness_of_fit(self) -> Optional[dict[str, Any]]: ...
    @property
    def background(self) -> dict[str, Any]: ...
    @property
    def unfit(self) -> Optional[list[dict[str, Any]]]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def per_shot(self) -> dict[str, npt.NDArray[Any]]: ...
    @property
    def crlb(self) -> Optional[dict[str, float]]: ...
    def summary(self) -> str: ...

def identify(
    model: Model,
    dataset: Dataset,
    *,
    joint: bool = False,
    force_model: Literal["auto", "free", "gain_per_measurement", "gain_per_mode"] = "auto",
    nominal_hz: Optional[Mapping[str, float]] = None,
    near_rel: Optional[float] = None,
    unweighted: bool = False,
    estimator: Literal["ml", "linear"] = "ml",
    crlb: bool = False,
    error_floor: bool = False,
    background: Optional[str] = None,
    rank_tol: Optional[float] = None,
    gls: Optional[bool] = None,
    gls_iterations: Optional[int] = None,
    sample_covariance: Optional[bool] = None,
    holdout: Optional[Sequence[str]] = None,
) -> IdentifyResult: ...
def compare(
    dataset: Dataset,
    models: Sequence[tuple[str, Model]],
    *,
    force_model: Literal["auto", "free", "gain_per_measurement", "gain_per_mode"] = "auto",
    holdout: Sequence[str] = (),
    error_floor: bool = False,
    background: Optional[str] = None,
) -> dict[str, Any]: ...
def discover(
    model: Model,
    dataset: Dataset,
    degrees: Sequence[int],
    *,
    potential: bool = False,
    alpha: float = 0.01,
    max_terms: int = 10,
    force_model: Literal["auto", "free", "gain_per_measurement", "gain_per_mode"] = "auto",
    velocities: bool = False,
    holdout: Sequence[str] = (),
    error_floor: bool = False,
    min_improvement: float = 0.05,
    background: Optional[str] = None,
    nonsmooth: bool = False,
) -> dict[str, Any]: ...
def mix(
    model: Model,
    drives: Sequence[tuple[str, Sequence[float]]],
    sidebands: Optional[int] = None,
    window_hz: Optional[float] = None,
    nominal_hz: Optional[Mapping[str, float]] = None,
) -> list[dict[str, Any]]: ...
def sweep(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    f_from_hz: float,
    f_to_hz: float,
    force: Mapping[str, float],
    *,
    points: int = 2000,
    harmonics: int = 3,
    two_tone_spacing_hz: Optional[float] = None,
    limit_cycles: bool = False,
) -> dict[str, Any]:
    """A frequency-response curve followed through folds (`harmonid sweep`). `points` is a
    resolution: consecutive points at most `|f_to_hz - f_from_hz| / points` apart in frequency,
    so a single-tone curve gets at least about `points + 1` points, more around folds (at most
    `8 * points`); with `two_tone_spacing_hz`, grid steps of the centre each way."""
def response(
    model: Model,
    result: IdentifyResult,
    dataset: Dataset,
    sweep: str,
) -> dict[str, Any]:
    """The frequency response of the stepped sweep `sweep` and of every sweep of its drive
    level, measured and as the identified model gives it (the data of `harmonid report`'s
    frequency-response figure): `family`, `level`, `unit` (the dataset's; every `x` is in it),
    `point`, `notes`; `sweeps` (per sweep `name`, `direction`, `steps`, `f_hz`, complex `x`
    with its phase against the step's identified force, `amplitude`, `phase_rad`, and the model
    at each step `model_x`, `model_amplitude`, `model_phase_rad`); `model` (None without one):
    the curve through its folds, `f_hz`, `x`, `amplitude`, `phase_rad`, `stable`, `force`
    (N/kg per mode), `harmonics`."""
    ...
def states(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    *,
    drives: Mapping[str, Sequence[float]] = ...,
    force: Mapping[str, float] = ...,
    pumps: Sequence[Sequence[float]] = ...,
    lattice: bool = True,
) -> dict[str, Any]:
    """Every steady state under one drive tone (`drives` {mode: [Hz]}, `force` {mode: N/kg})
    and/or a pump (`pumps` [(Hz, level[, phase_rad])]), as `harmonid states --json`: `tone_hz`,
    `paths`, `complex_solutions`, `at_infinity`, `failed`, and `states`, each with `amplitudes`
    (complex, m, per mode), `stable`, `oscillatory` (unstable through a complex pair of the slow
    flow, Hopf type; false for a saddle), `eigenvalues` (slow flow, 1/s) and, with `lattice`,
    `lattice` (`continued`, `stable`, `growth_rate`, `shift`, `same_as` or `why`)."""
    ...
def phase_diagram(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    x: tuple[str, float, float, int],
    y: tuple[str, float, float, int],
    *,
    drives: Mapping[str, Sequence[float]] = ...,
    force: Mapping[str, float] = ...,
    pumps: Sequence[Sequence[float]] = ...,
    time_budget: Optional[float] = None,
) -> dict[str, Any]:
    """The count of stable and unstable single-harmonic steady states over a plane, as
    `harmonid phase-diagram`: `x`, `y` each `(axis, from, to, n)` with axis "freq", "force:q1",
    "pump_hz", "pump_level" or a parameter; returns `x`, `y`, `stable`, `unstable`,
    `oscillatory` (of the unstable, those through a complex pair: Hopf type) (int arrays
    of shape (len(y), len(x)), -1 where the time budget left a row out), `generic_count`,
    `complete`."""
    ...
def linear_response(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    probe: str,
    probe_hz: Sequence[float],
    *,
    drives: Mapping[str, Sequence[float]] = ...,
    force: Mapping[str, float] = ...,
    pumps: Sequence[Sequence[float]] = ...,
    probe_force: float = 1.0,
    noise_psd: Optional[float] = None,
) -> dict[str, Any]:
    """The linear response of every mode to a weak probe tone on `probe` at each of `probe_hz`
    about the drive ramp's steady state under `drives` ({mode: [Hz]}) with `force` ({mode: N/kg})
    and `pumps` ([(Hz, level[, phase_rad])]), or about rest: `probe_hz`, `offsets_hz` (the
    response lines at f_p + offset; negative totals are idlers), `amplitudes` (N, modes, lines;
    complex, m), `idler_offset_hz`, `modes`, `stable`, and with `noise_psd=S_F` ((N/kg)^2/Hz)
    `noise_psd` (N, modes; m^2/Hz)."""
    ...
def simulate(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    plan: Union[Mapping[str, Any], PlanResult, _Path],
    *,
    time_domain: Union[bool, Mapping[str, Union[bool, int, float]], None] = None,
    seed: int = 0,
    noise: bool = True,
    check_stability: bool = True,
    allow_unstable: bool = False,
    allow_truncation: bool = False,
    order: Optional[int] = None,
) -> Dataset: ...

class PlanResult:
    @property
    def toml(self) -> str: ...
    @property
    def plan(self) -> dict[str, Any]: ...
    @property
    def bounds(self) -> dict[str, dict[str, Any]]: ...
    @property
    def quantities(self) -> dict[str, dict[str, Optional[float]]]: ...
    @property
    def findings(self) -> list[dict[str, str]]: ...
    @property
    def condition(self) -> Optional[float]: ...
    @property
    def shots(self) -> int: ...
    def table(self) -> str: ...

def plan(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    noise_m: float,
    shots: int = 1,
    *,
    max_frequencies: int = 32,
    max_measurements: Optional[int] = None,
    bandwidth_hz: float = 0.5,
    max_force: Optional[float] = None,
    points: Optional[Sequence[Mapping[str, float]]] = None,
    nominal: bool = False,
    draws: int = 10,
    ladder: Optional[Sequence[float]] = None,
    gains: Optional[Mapping[str, float]] = None,
    max_voltage: Optional[float] = None,
    instrument: Optional[str] = None,
    filter_order: Optional[int] = None,
) -> PlanResult: ...
def evaluate_plan(
    model: Model,
    values: Union[Mapping[str, Any], IdentifyResult, _Path],
    plan: Union[Mapping[str, Any], PlanResult, _Path],
    noise_m: float,
    shots: int = 1,
    *,
    nominal: bool = False,
    draws: int = 10,
) -> PlanResult: ...
def read_table(
    files: Sequence[_Path], mapping: _Path, *, drop_nan_rows: bool = False
) -> Dataset: ...
def read_zi_csv(
    files: Sequence[_Path],
    *,
    amplitude: str,
    quadrature: str,
    metres_per_unit: Optional[float],
    clockbase_hz: float,
    response: str = "displacement",
    drive_level: Optional[float] = None,
    settle_s: Optional[float] = None,
    settle_samples: Optional[int] = None,
) -> Dataset: ...
def read_zi_hdf5(
    files: Sequence[_Path],
    *,
    amplitude: str,
    quadrature: str,
    metres_per_unit: Optional[float],
    clockbase_hz: float,
    demods: Optional[Sequence[int]] = None,
    response: str = "displacement",
    drive_level: Optional[float] = None,
    settle_s: Optional[float] = None,
    settle_samples: Optional[int] = None,
) -> Dataset: ...
def read_moku_csv(
    files: Sequence[_Path],
    *,
    channels: str,
    output_gain: float,
    amplitude: str,
    quadrature: str,
    metres_per_unit: Optional[float],
    output_offset: float = 0.0,
    phase_unit: Optional[str] = None,
    demod_hz: Optional[Sequence[float]] = None,
    response: str = "displacement",
    drive_level: Optional[float] = None,
    settle_s: Optional[float] = None,
    settle_samples: Optional[int] = None,
) -> Dataset: ...
def read_zi_sweeper(
    files: Sequence[_Path],
    *,
    amplitude: str,
    quadrature: str,
    metres_per_unit: Optional[float],
    response: str = "displacement",
    drive_level: Optional[float] = None,
    drop_nan_rows: bool = False,
) -> Dataset: ...
