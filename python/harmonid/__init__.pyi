from collections.abc import Mapping, Sequence
from typing import Any, Literal, Optional, Union

from ._harmonid import (
    Dataset as Dataset,
    DatasetError as DatasetError,
    HarmonidError as HarmonidError,
    IdentifyError as IdentifyError,
    IdentifyResult as IdentifyResult,
    Model as Model,
    ModelError as ModelError,
    PlanError as PlanError,
    PlanResult as PlanResult,
    SimulationError as SimulationError,
    discover as discover,
    evaluate_plan as evaluate_plan,
    identify as identify,
    plan as plan,
    simulate as simulate,
    sweep as sweep,
    response as response,
    linear_response as linear_response,
    states as states,
    phase_diagram as phase_diagram,
)

from . import io as io

__version__: str

def mix(
    model: Model,
    drives: Union[Mapping[str, Sequence[float]], Sequence[tuple[str, Sequence[float]]]],
    *,
    sidebands: Optional[int] = None,
    window_hz: Optional[float] = None,
    nominal_hz: Optional[Mapping[str, float]] = None,
) -> list[dict[str, Any]]: ...
def compare(
    dataset: Dataset,
    models: Union[Mapping[str, Model], Sequence[tuple[str, Model]]],
    *,
    force_model: Literal["auto", "free", "gain_per_measurement", "gain_per_mode"] = "auto",
    holdout: Sequence[str] = (),
    error_floor: bool = False,
    background: Optional[str] = None,
) -> dict[str, Any]: ...
