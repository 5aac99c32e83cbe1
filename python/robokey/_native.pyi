"""Type stubs of the native module ``robokey._native`` (crates/robokey-py); use ``robokey``."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

__version__: str
METRIC_UNITS: Dict[str, str]
WORLD_PRESETS: List[str]

# (name, unit, description, dtype, data, valid): dtype is numpy's name of the values ("str":
# data is a list of str), data their native-endian bytes, valid a byte per row (None: all).
_Column = Tuple[str, str, str, str, Union[bytes, List[str]], Optional[bytes]]

class ConfigError(ValueError):
    origin: Optional[str]
    field: Optional[str]
    value: Optional[str]
    allowed: Optional[str]

class SweepError(ValueError): ...
class InputError(ValueError): ...
class SimulationError(RuntimeError): ...

class OptionError(ValueError):
    option: str
    value: str
    allowed: str

def run(config: Any = None, *, seed: Optional[int] = None, replicate: int = 0) -> Dict[str, Any]: ...
def sweep(
    config: Any,
    *,
    seed: Optional[int] = None,
    jobs: int = 0,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> Tuple[List[_Column], str]: ...
def secrecy(
    sweep: Any,
    *,
    seed: Optional[int] = None,
    adversaries: Optional[Sequence[str]] = None,
    epsilon: Optional[float] = None,
    block_bits: Optional[int] = None,
    blocks: int = 1,
    pooling: Optional[str] = None,
    sample_bits: int = 1000,
    max_sessions: Optional[int] = None,
    assume_eve_error: Optional[float] = None,
    jobs: int = 0,
) -> Tuple[str, List[_Column], Optional[str]]: ...
def read_sweep(folder: Union[str, "PathLike[str]"]) -> List[Tuple[str, List[_Column], str]]: ...
def read_trace(path: Union[str, "PathLike[str]"]) -> List[_Column]: ...
def read_capture(
    path: Union[str, "PathLike[str]"],
) -> Tuple[
    List[Tuple[int, Optional[int], Optional[int], Optional[int], Optional[int], List[float], Optional[str]]],
    List[str],
]: ...
def list_keys(
    store: Union[str, "PathLike[str]"],
    pairing: Union[str, "PathLike[str]"],
    insecure_pairing_file: bool = False,
) -> Tuple[str, Optional[str]]: ...
