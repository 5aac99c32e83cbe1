"""robokey from Python: the library itself, not the command line parsed.

A remotely controlled robot and its controller agree on a secret key through the robot's
motion, and robokey says how secret that key is (docs/python.md, README.md). This package calls
the Rust library: the numbers are those of the ``robokey`` command for the same configuration
and seed, bit for bit.

Configurations are None (the defaults), a dict (``{"protocol": {"delta_v": 0.035}}``, or
dotted top-level keys ``{"protocol.delta_v": 0.035}``) or a TOML string, validated with the
library's named errors: :class:`ConfigError` carries ``field``, ``value`` and ``allowed``.
Tables are :class:`pyarrow.Table` (``.to_pandas()``, ``polars.from_arrow``,
``.column(name).to_numpy()``), each column's unit in its field's metadata (``b"unit"``).
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import pyarrow as pa
import pyarrow.parquet

from . import _native
from ._native import ConfigError, InputError, OptionError, SimulationError, SweepError

__version__: str = _native.__version__

#: The unit of each metric (``runs.csv``'s and ``metrics.json``'s columns); empty for counts
#: and flags.
METRIC_UNITS: Dict[str, str] = dict(_native.METRIC_UNITS)

#: The names of the world presets (docs/world.md): a configuration's ``{"world": {"preset":
#: name}}`` simulates that world (its fields, when given, override the preset's).
WORLD_PRESETS: List[str] = list(_native.WORLD_PRESETS)

Config = Union[None, str, Mapping[str, Any]]
"""A configuration: None (the defaults), a TOML string or a dict."""

Progress = Union[None, bool, Callable[[int, int], Any]]
"""How a long computation shows its progress: None (a tqdm bar if tqdm is installed, else
nothing), False (nothing), True (a tqdm bar, which must be installed) or a callable
``progress(done, total)``."""

__all__ = [
    "ConfigError",
    "FRAME_SCHEMA",
    "InputError",
    "KEY_SCHEMA",
    "METRIC_UNITS",
    "OptionError",
    "WORLD_PRESETS",
    "SimulationError",
    "SweepError",
    "eve",
    "list_keys",
    "read_capture",
    "read_sweep",
    "read_trace",
    "run",
    "secrecy",
    "sweep",
    "threat",
]

_Column = Tuple[str, str, str, str, Any, Optional[bytes]]


def _array(dtype: str, data: Any, valid: Optional[bytes]) -> pa.Array:
    """One column's values as an Arrow array, undefined values null."""
    if dtype == "str":
        return pa.array(data, type=pa.string())
    values = np.frombuffer(data, dtype=np.dtype(dtype))
    if valid is None:
        return pa.array(values)
    return pa.array(values, mask=~np.frombuffer(valid, dtype=np.bool_))


def _table(columns: List[_Column], metadata: Optional[Dict[str, str]] = None) -> pa.Table:
    """The columns the native module hands over as an Arrow table; each field's metadata holds
    its unit (``b"unit"``) and, where known, what it means (``b"description"``)."""
    arrays = []
    fields = []
    for name, unit, description, dtype, data, valid in columns:
        array = _array(dtype, data, valid)
        field_metadata = {"unit": unit}
        if description:
            field_metadata["description"] = description
        arrays.append(array)
        fields.append(pa.field(name, array.type, nullable=True, metadata=field_metadata))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=metadata))


def _progress_callable(progress: Progress, label: str) -> Tuple[Optional[Callable[[int, int], Any]], Callable[[], None]]:
    """The callable a native computation reports ``(done, total)`` to, and what closes it."""
    if progress is False:
        return None, lambda: None
    if callable(progress):
        return progress, lambda: None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        if progress is True:
            raise
        return None, lambda: None
    bar: Any = None

    def report(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc=label, unit="run")
        bar.update(done - bar.n)

    def close() -> None:
        if bar is not None:
            bar.close()

    return report, close


def run(config: Config = None, *, seed: Optional[int] = None, replicate: int = 0) -> Dict[str, Any]:
    """One simulated session, as ``robokey run`` makes it, without writing files.

    ``seed`` sets ``run.seed`` (as ``--seed``), ``replicate`` the replicate (``--replicate``).
    Returns a dict:

    - ``metrics``: ``metrics.json``'s columns in order (``METRIC_UNITS`` has their units),
      None where undefined (e.g. ``correct_pct`` when nothing was accepted);
    - ``trace``: every row of ``trace.csv`` (k = 0 … N) as an Arrow table, undefined cells null;
    - ``table``: the metrics as ``robokey run`` prints them;
    - ``config``: the resolved configuration as TOML; ``seed``, ``replicate``.

    Raises :class:`ConfigError` for an invalid configuration, :class:`SimulationError` if the
    session aborts.
    """
    result = _native.run(config, seed=seed, replicate=replicate)
    columns = result.pop("trace_columns")
    result["trace"] = _table(columns, {"robokey.config": result["config"]})
    return result


def sweep(
    config: Config,
    *,
    seed: Optional[int] = None,
    jobs: int = 0,
    progress: Progress = None,
) -> pa.Table:
    """Runs a sweep as ``robokey sweep`` does, in parallel on ``jobs`` threads (0: one per core)
    with the GIL released, and returns its runs as an Arrow table, one row per run in run order:
    a column per swept field, ``replicate``, then the metrics — ``runs.csv``'s columns and
    values for the same definition and seed, whatever ``jobs``.

    ``config`` is a configuration with a ``sweep`` table (as a sweep file:
    ``{"run": {"replicates": 10}, "sweep": {"protocol.delta_v": [0.02, 0.035]}}``, ranges as
    ``{"start": …, "stop": …, "step": …}``, ``"mode": "zip"``); ``sweep.traces`` is ignored (use
    :func:`run` for a trace). The table's metadata ``robokey.sweep`` holds the resolved
    definition. Ctrl-C stops the sweep once the running runs end and raises KeyboardInterrupt.

    Raises :class:`ConfigError`, :class:`SweepError` for a bad axis or a suite of experiments,
    :class:`SimulationError` if a session aborts.
    """
    report, close = _progress_callable(progress, "sweep")
    try:
        columns, resolved = _native.sweep(config, seed=seed, jobs=jobs, progress=report)
    finally:
        close()
    return _table(columns, {"robokey.sweep": resolved})


def _block_rows(results: List[Dict[str, Any]]) -> List[Dict[str, Any]]:
    """One row per privacy-amplification block of every point and adversary; the realised
    view's fields prefixed ``realised_``."""
    rows = []
    for result in results:
        for index, block in enumerate(result["blocks"]):
            row: Dict[str, Any] = {
                "point": result["point"],
                "adversary": result["adversary"],
                "adversary_class": result["adversary_class"],
                "block": index,
            }
            for key, value in block.items():
                if key == "realised":
                    row.update({f"realised_{k}": v for k, v in value.items()})
                else:
                    row[key] = value
            rows.append(row)
    return rows


def secrecy(
    sweep: Union[Config, "os.PathLike[str]"],
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
) -> Dict[str, Any]:
    """How many of a sweep's agreed bits are secret, and against whom, as ``robokey secrecy``
    computes it (docs/secrecy.md), without writing files.

    ``sweep`` is a sweep definition (as :func:`sweep` takes it) or a sweep folder written by
    ``robokey sweep`` (a :class:`pathlib.Path`; a ``str`` is TOML). The keywords are the
    command's options: ``adversaries`` (``"oracle"``, ``"mismatch"``, ``"soft"``,
    ``"identify"``, ``"transcript"``, ``"camera"``, ``"commands"``; default: the sensing
    mode's), ``epsilon`` (``--eps``), ``block_bits`` (``--block``), ``blocks``, ``pooling``
    (``"confirmed"`` or ``"complete"``), ``sample_bits``, ``max_sessions`` (default: 2,000 per 10,000 bits of
    blocks), ``assume_eve_error``; unset ones take the sweep's ``[secrecy]`` table, then the defaults
    (the reconciliation and sizing too: the table's ``reconciliation`` and ``sizing``, else
    Cascade and the configured plant).

    Returns a dict: ``table`` (``secrecy.csv``'s columns and values, as ``secrecy.parquet``
    types them, each column's unit and meaning in its metadata: one row per point and
    adversary, strongest class first — ℓ in ``secret_bits``, the realised bound in
    ``realised_secret_bits``),
    ``blocks`` (one row per privacy-amplification block: its sessions, bits, leak, ℓ and the
    adversary's realised view), ``results`` (``secrecy.json``'s results, every detail),
    ``epsilon``, ``block_bits``, ``pooling`` and ``map`` (private sensing's map, else None).

    Raises :class:`OptionError` for an option out of range, :class:`InputError` for an unknown
    adversary or pooling or a folder that is not a sweep's, :class:`ConfigError` and
    :class:`SweepError` for a definition that is not valid.
    """
    secrecy_json, columns, map_json = _native.secrecy(
        sweep,
        seed=seed,
        adversaries=None if adversaries is None else list(adversaries),
        epsilon=epsilon,
        block_bits=block_bits,
        blocks=blocks,
        pooling=pooling,
        sample_bits=sample_bits,
        max_sessions=max_sessions,
        assume_eve_error=assume_eve_error,
        jobs=jobs,
    )
    data = json.loads(secrecy_json)
    return {
        "table": _table(columns),
        "blocks": pa.Table.from_pylist(_block_rows(data["results"])),
        "results": data["results"],
        "epsilon": data["epsilon"],
        "block_bits": data["block_bits"],
        "pooling": data["pooling"],
        "map": None if map_json is None else json.loads(map_json),
    }


def threat(
    config: Config = None,
    *,
    seed: Optional[int] = None,
    camera_std: Optional[Sequence[float]] = None,
    fps: Optional[Sequence[float]] = None,
    frame_std: Optional[Sequence[float]] = None,
    jobs: int = 0,
) -> Dict[str, Any]:
    """What a camera of Eve's leaves of the key at ``config`` (evaluated in private sensing), as
    ``robokey threat`` computes it (docs/threat-model.md), without printing.

    Cameras: ``camera_std`` (mm per sample instant), or every combination of ``fps``
    (frames/s) and ``frame_std`` (mm per frame, white), given together; none: the
    configuration's own statement. Returns a dict: ``cameras`` (per camera its ``statement``,
    ``per_instant_mm``, ``raw_bits``, ``secret_bits`` ℓ, ``bits_per_step``,
    ``bits_per_second`` and ``zero_reason``), ``break_even`` (``kind`` ``between`` with
    ``zero_at_mm`` and ``positive_at_mm`` per instant, or ``below``/``above`` with ``mm``),
    ``sample_time``, ``block_bits`` and ``epsilon``.

    Raises :class:`ConfigError` for a configuration or camera out of range, :class:`InputError`
    for ``fps`` without ``frame_std`` or the reverse.
    """
    figures: Dict[str, Any] = json.loads(
        _native.threat(
            config,
            seed=seed,
            camera_std=None if camera_std is None else list(camera_std),
            fps=None if fps is None else list(fps),
            frame_std=None if frame_std is None else list(frame_std),
            jobs=jobs,
        )
    )
    return figures


def _parquet_runs(folder: str) -> Union[None, pa.Table, Dict[str, pa.Table]]:
    """The ``runs.parquet`` of a sweep folder, or of each experiment folder of a suite folder
    (by name); None when there is none."""
    if os.path.isfile(os.path.join(folder, "runs.parquet")):
        return pyarrow.parquet.read_table(os.path.join(folder, "runs.parquet"))
    if not os.path.isdir(folder):
        return None
    names = sorted(
        name for name in os.listdir(folder) if os.path.isfile(os.path.join(folder, name, "runs.parquet"))
    )
    if not names:
        return None
    return {name: pyarrow.parquet.read_table(os.path.join(folder, name, "runs.parquet")) for name in names}


def read_sweep(folder: "os.PathLike[str] | str") -> Union[pa.Table, Dict[str, pa.Table]]:
    """The runs of a sweep folder that ``robokey sweep`` (or ``reproduce``) wrote, read back as
    robokey's reports read them — the same table :func:`sweep` returns for its definition; a
    suite folder gives a dict of tables by experiment name.

    A folder swept with ``--format parquet`` is read from its ``runs.parquet`` (the same
    columns, units and meanings; written only once the folder holds every run).

    Raises :class:`InputError` for a folder that is not a complete sweep's (interrupted, a
    shard only, a file that does not read back), OSError for a file that cannot be read.
    """
    parquet = _parquet_runs(os.fspath(folder))
    if parquet is not None:
        return parquet
    experiments = _native.read_sweep(os.fspath(folder))
    tables = {
        name: _table(columns, {"robokey.sweep": resolved})
        for name, columns, resolved in experiments
    }
    if len(experiments) == 1 and experiments[0][0] == "":
        return tables[""]
    return tables


def read_trace(path: "os.PathLike[str] | str") -> pa.Table:
    """A ``trace.csv`` (of ``robokey run``, or a sweep's ``traces/point-<i>.csv``) as the
    table :func:`run` returns as ``trace``; a ``.parquet`` trace (``--format parquet``) is read
    as it is. Raises :class:`InputError` naming the line that does not read back."""
    if os.fspath(path).endswith(".parquet"):
        return pyarrow.parquet.read_table(os.fspath(path))
    return _table(_native.read_trace(os.fspath(path)))


#: The columns of :func:`read_capture`'s table.
FRAME_SCHEMA = pa.schema(
    [
        pa.field("index", pa.int64(), metadata={"description": "the datagram's position in the capture (1 for the first)"}),
        pa.field("type", pa.uint8(), metadata={"description": "the frame's type byte (header byte 3); null when undecodable"}),
        pa.field("session", pa.uint32(), metadata={"description": "session number; null when undecodable"}),
        pa.field("seq", pa.uint32(), metadata={"description": "sequence number; null when undecodable"}),
        pa.field("step", pa.uint32(), metadata={"description": "control step k (header bytes 12..16); null when undecodable"}),
        pa.field("numbers", pa.list_(pa.float64()), metadata={"description": "a Measurement's y, a Command's u0 then u1, a DoubletCommand's sample, first and second; empty for other frames"}),
        pa.field("error", pa.string(), metadata={"description": "why the datagram does not decode as a robokey frame; null when it does"}),
    ]
)


def read_capture(path: "os.PathLike[str] | str") -> pa.Table:
    """The robokey frames of a pcap or pcapng capture (the relay's, tcpdump's, dumpcap's), as
    ``robokey frames`` lists them — one row per UDP datagram in capture order: ``index``,
    ``type``, ``session``, ``seq``, ``step``, ``numbers`` and, for a datagram that does not
    decode, ``error`` (the other fields null). MACs are not checked: nothing secret is read.

    What of the capture could not be used (a cut-off end, packets cut by the snap length, link
    types robokey does not read) is warned of (``UserWarning``, as the command warns on
    stderr). Raises :class:`InputError` for a file that is not a capture robokey reads,
    OSError for one that cannot be read.
    """
    rows, shortfalls = _native.read_capture(os.fspath(path))
    for shortfall in shortfalls:
        warnings.warn(f"{os.fspath(path)}: {shortfall}", stacklevel=2)
    columns: List[Sequence[Any]] = list(zip(*rows)) if rows else [[] for _ in FRAME_SCHEMA]
    return pa.Table.from_arrays(
        [pa.array(list(column), type=field.type) for column, field in zip(columns, FRAME_SCHEMA)],
        schema=FRAME_SCHEMA,
    )


_Path = Union[str, "os.PathLike[str]"]


def _paths(value: Union[None, _Path, Sequence[_Path]]) -> List[str]:
    """None, one path or a sequence of paths, as a list of paths."""
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [os.fspath(value)]
    return [os.fspath(v) for v in value]


def eve(
    capture: Union[_Path, Sequence[_Path]],
    config: Config = None,
    *,
    camera_log: Union[None, _Path, Sequence[_Path]] = None,
    robot_key: Union[None, _Path, Sequence[_Path]] = None,
    controller_key: Union[None, _Path, Sequence[_Path]] = None,
    block: Optional[_Path] = None,
    strategy: Union[None, str, Sequence[str]] = None,
    errors: Optional[Sequence[float]] = None,
    seed: Optional[int] = None,
) -> Dict[str, Any]:
    """The eavesdroppers on a recorded session, as ``robokey eve --capture`` runs them: the
    dict is the ``capture.json`` the command writes with ``--out`` for the same inputs.

    ``config`` is the sessions' configuration (as :func:`run` takes it; a capture whose
    ``Hello`` carries other terms raises :class:`InputError` naming them), ``seed`` its
    ``run.seed`` (her starting errors are drawn from it). In odometry sensing ``capture`` is one
    pcap or pcapng file; ``strategy`` one name or several (default the configuration's
    ``eve.strategy``), ``errors`` her starting relative errors ``(r, D, W, V)``, each in
    (−1, 1) (every strategy but the oracle), ``controller_key`` the controller's key file, to
    measure her disagreement. The dict has ``session``, ``session_aborted``, ``frames``,
    ``undecodable``, ``shortfalls`` and per strategy its ``start_errors``, ``end_errors``,
    ``decisions`` (per step: 0, 1 or None), ``key_bits``, ``tag_flips`` and
    ``disagreement_pct``.

    In private sensing (``{"sensing": {"mode": "private"}}``) ``capture``, ``camera_log`` (her
    camera's pose log, ``robokey record``), ``robot_key`` and ``controller_key`` are one per
    session, in the same order; per strategy (``camera``, ``commands``) every doublet's
    ``llr``, ``bits`` and ``llr_given_others``. With ``block`` (an agent's ``--report`` of the
    run in which the sessions' block ended) the dict is ``{"sessions": […], "block": …}``,
    ``block`` her realised bound (``realised_bits``) beside the key the agents committed
    (``committed_bits``), ``exceeds`` and how the world differs from the parties' (``world``).

    What of a capture could not be read is warned of (``UserWarning``). Raises
    :class:`ConfigError` for an invalid configuration, :class:`InputError` for inputs that do not
    fit the mode or each other (named as these keywords), a file that is not what it should be
    or a block of another size than the sessions', OSError for a file that cannot be read.
    """
    strategies = [strategy] if isinstance(strategy, str) else list(strategy or [])
    report, shortfalls = _native.eve(
        _paths(capture),
        config,
        camera_log=_paths(camera_log),
        robot_key=_paths(robot_key),
        controller_key=_paths(controller_key),
        block=None if block is None else os.fspath(block),
        strategy=strategies,
        errors=None if errors is None else [float(e) for e in errors],
        seed=seed,
    )
    for shortfall in shortfalls:
        warnings.warn(shortfall, stacklevel=2)
    result: Dict[str, Any] = json.loads(report)
    return result


#: The columns of :func:`list_keys`'s table (``robokey keys list --json``'s fields).
KEY_SCHEMA = pa.schema(
    [
        pa.field("id", pa.string()),
        pa.field("role", pa.string()),
        pa.field("block", pa.uint64()),
        pa.field("bits", pa.uint64(), metadata={"unit": "bit"}),
        pa.field("available_bits", pa.uint64(), metadata={"unit": "bit"}),
        pa.field("taken_bits", pa.uint64(), metadata={"unit": "bit"}),
        pa.field("taken", pa.list_(pa.string())),
        pa.field("epsilon", pa.float64()),
        pa.field("label", pa.string()),
        pa.field("status", pa.string()),
        pa.field("pending_reason", pa.string()),
        pa.field("assumption", pa.string()),
        # Private sensing: what the key rests on (null in odometry mode and older records).
        pa.field("basis", pa.struct([pa.field("camera", pa.string()), pa.field("plant", pa.string())])),
        # How the key's block was reconciled (cascade or ldpc) and its leak_EC (null in older records).
        pa.field("reconciliation", pa.string()),
        pa.field("leak_ec", pa.uint64(), metadata={"unit": "bit"}),
        pa.field("created", pa.string()),
        pa.field("sessions", pa.list_(pa.uint32())),
    ]
)


def list_keys(
    store: "os.PathLike[str] | str",
    pairing: "os.PathLike[str] | str",
    *,
    insecure_pairing_file: bool = False,
) -> pa.Table:
    """The final keys of an agent's store, as ``robokey keys list --json`` lists them — never
    their bits: one row per key with its ``id``, ``role``, ``block``, ``bits``,
    ``available_bits`` (deliverable once settled), ``taken_bits``, ``taken`` (the IDs of the
    keys taken from it), ``epsilon``, ``label`` (``physical`` or ``restricted``), ``status``
    (``settled`` or ``pending``, with ``pending_reason``), ``assumption`` (about Eve),
    ``basis`` (private sensing: the ``camera`` and ``plant`` model class it rests on),
    ``reconciliation`` (``cascade`` or ``ldpc``) and ``leak_ec`` (bits; both null in records
    written before they were kept), ``created`` and ``sessions``.

    Every key file is verified under a key derived from the pairing file (``pairing``), so a
    file planted beside the store is refused. ``insecure_pairing_file`` accepts a pairing file
    open to others (warned of), as ``--insecure-pairing-file`` does. Raises
    :class:`InputError` for a folder that is not a store, a store of another pairing, a
    malformed key file or a pairing file that is missing or open to others, OSError for a
    failed read.
    """
    listing, warning = _native.list_keys(
        os.fspath(store), os.fspath(pairing), insecure_pairing_file
    )
    if warning is not None:
        warnings.warn(warning, stacklevel=2)
    return pa.Table.from_pylist(json.loads(listing), schema=KEY_SCHEMA)
