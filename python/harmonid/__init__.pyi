import os
from collections.abc import Mapping, Sequence
from typing import Any, Optional, Union

from ._harmonid import (
    Dataset as Dataset,
    DatasetError as DatasetError,
    HarmonidError as HarmonidError,
    IdentifyError as IdentifyError,
    IdentifyResult as IdentifyResult,
    Model as Model,
    ModelError as ModelError,
    SimulationError as SimulationError,
    identify as identify,
)

__version__: str

def mix(
    model: Model,
    drives: Union[Mapping[str, Sequence[float]], Sequence[tuple[str, Sequence[float]]]],
    *,
    sidebands: Optional[int] = None,
    window_hz: Optional[float] = None,
    nominal_hz: Optional[Mapping[str, float]] = None,
) -> list[dict[str, Any]]: ...

def sweep(
    model: Model,
    values: Union[Mapping[str, Any], str, "os.PathLike[str]"],
    f_from_hz: float,
    f_to_hz: float,
    force: Mapping[str, float],
    *,
    points: int = 2000,
    harmonics: int = 3,
    two_tone_spacing_hz: Optional[float] = None,
) -> dict[str, Any]: ...
