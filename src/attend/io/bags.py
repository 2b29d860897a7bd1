"""ROS bags and MCAP files read as logs: ROS 1 ``.bag``, ROS 2 bags (a folder with
``metadata.yaml``, or its ``.db3`` file) and ``.mcap`` files become the same :class:`~attend.io.Log`
a CSV gives. Reading needs the optional package rosbags (pure Python, no ROS install):
``pip install "attend[ros]"``.

Each column of the log is one numeric field of the messages on one topic; the topics, each at
its own rate, are put on one uniform time grid. The model file says how, in its [log] section
(a CSV model file needs none of this and stays valid; a CSV log ignores these keys)::

    [log]
    rate_hz = 100                 # grid rate [Hz] (or dt = 0.01 [s]); default: [model] dt, else
                                  # the median message interval of grid_topic
    grid_topic = "/imu/data"      # the grid starts at this topic's first message inside the
                                  # common span (default: the fastest topic named below)
    resample = "linear"           # "linear" (default) or "hold" (sample-and-hold)
    stamps = "auto"               # "auto" (default): header.stamp where the message type has a
                                  # std_msgs/Header, else the bag's receive time; "header"; "receive"
    max_gap = 0.05                # s: a longer silence of a topic is a dropout (default: 5 of the
                                  # topic's median intervals)

    [log.columns]                 # one entry per output and measured-input column of the file
    gyro_x = { topic = "/imu/data", field = "angular_velocity.x" }
    motor_1 = { topic = "/motors", field = "data[0]" }   # [i]: element i of an array, from 0

The grid, in integer nanoseconds of the chosen stamps:

- span: from the latest first message to the earliest last message over the columns, so every
  grid time lies between two messages of every column (nothing is extrapolated);
- times t_k = t_0 + round(k dt), t_0 the first message of grid_topic inside the span, for every
  t_k in the span; the log's time column is t_k - t_0 in seconds (the bag time of t_0 is in
  :attr:`~attend.io.Log.origin`);
- values: "linear": v_j + (t_k - s_j) / (s_{j+1} - s_j) (v_{j+1} - v_j) between the messages
  s_j <= t_k < s_{j+1} around t_k (a message exactly at t_k gives its own value); "hold": v_j of
  the latest message s_j <= t_k;
- a NaN field is a missing message of that column (left out before resampling); a grid time
  strictly inside a dropout (two messages of a column further apart than max_gap) is missing
  (NaN): with ``gaps=True`` (`attend estimate`) the estimators skip it like an empty CSV cell,
  otherwise (`attend identify`) it is an error.

A slower topic is upsampled: its values are repeated ("hold") or interpolated ("linear") and the
estimators take each grid sample as a measurement. Refused, in one line naming the file and the
topic, field or key: a topic missing from the bag or without messages, a field not in the message
type or not a number (a string, a message, an array without an index), stamps that repeat or go
backwards, inf or a value beyond +-1e150, topics without a common span of two grid samples, and a
grid faster than every topic named (a grid finer than the data invents samples).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from attend._validation import LARGEST_MAGNITUDE, AttendInputError
from attend.io.fields import _text

BAG_SUFFIXES = (".bag", ".mcap", ".db3")
"""File name endings read as bags: ROS 1 .bag, MCAP .mcap, ROS 2 sqlite3 .db3 (a ROS 2 bag folder,
with metadata.yaml, is one too)."""

RESAMPLE_RULES = ("linear", "hold")
STAMP_SOURCES = ("auto", "header", "receive")

GAP_INTERVALS = 5.0
"""Default dropout: a silence longer than this many of the topic's median message intervals."""

RATE_TOLERANCE = 0.01
"""A grid step may be this much (relative) shorter than the fastest topic's median interval."""

_LOG_BAG_KEYS = {"rate_hz", "dt", "grid_topic", "resample", "stamps", "max_gap", "columns"}
_SEGMENT = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?")
_NODE_BASE, _NODE_NAME, _NODE_ARRAY, _NODE_SEQUENCE = 1, 2, 3, 4  # rosbags.interfaces.Nodetype
_TEXT_TYPES = ("string", "wstring")


@dataclass(frozen=True)
class BagColumn:
    """One log column read from a bag: name: the column (as the model file's [outputs] columns and
    [[inputs]] column name it); topic: the topic, e.g. "/imu/data"; field: the path of a numeric
    field in its messages, e.g. "angular_velocity.x" or "data[0]" (array elements from 0)."""

    name: str
    topic: str
    field: str

    @property
    def path(self) -> tuple[tuple[str, int | None], ...]:
        """The field as (name, index or None) steps: "poses[2].position.x" -> (("poses", 2),
        ("position", None), ("x", None))."""
        return tuple((match[1], None if match[2] is None else int(match[2]))
                     for match in (_SEGMENT.fullmatch(part) for part in self.field.split(".")))


@dataclass(frozen=True)
class BagLayout:
    """How a bag becomes a log (the model file's [log] section, module docstring).

    columns: one :class:`BagColumn` per log column; dt: the grid step [s] ([log] rate_hz or dt,
    else [model] dt; None: the median message interval of the grid topic); grid_topic: the topic
    whose first message in the common span starts the grid (None: the fastest topic of columns);
    resample: "linear" or "hold"; stamps: "auto" (header.stamp where the message type has a
    header, else receive time), "header" or "receive"; max_gap: the longest silence of a column
    that is not a dropout [s] (None: GAP_INTERVALS of its topic's median message intervals).
    """

    columns: tuple[BagColumn, ...]
    dt: float | None = None
    grid_topic: str | None = None
    resample: str = "linear"
    stamps: str = "auto"
    max_gap: float | None = None

    @property
    def topics(self) -> tuple[str, ...]:
        """The topics read, in the order of their first column."""
        return tuple(dict.fromkeys(column.topic for column in self.columns))


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` is read as a bag: a name ending in .bag, .mcap or .db3, or a folder with
    metadata.yaml (a ROS 2 bag)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix.lower() in BAG_SUFFIXES


def bag_layout(section: dict, path: str | Path, model_dt: float | None, used_columns: dict[str, str]) -> BagLayout | None:
    """The model file's [log] section as a :class:`BagLayout` (None: no [log.columns], a CSV-only
    file). section: the [log] table; path: the model file (errors name it); model_dt: [model] dt
    [s] or None; used_columns: the columns the model reads (name -> where the file names it, e.g.
    "[outputs] columns"), each of which needs an entry in [log.columns]."""
    where, in_columns = f"{path}: [log]", f"{path}: [log.columns]"
    given = sorted(set(section) & (_LOG_BAG_KEYS - {"columns"}))
    if "columns" not in section:
        if given:
            raise AttendInputError(f"{where} {', '.join(given)}: settings for reading a ROS bag; add a [log.columns] "
                                   "table naming the topic and field of each column (or remove them for a CSV log)")
        return None
    table = section["columns"]
    if not isinstance(table, dict) or not table:
        raise AttendInputError(f"{where} columns: expected a table of columns, e.g. "
                               f'[log.columns] gyro_x = {{ topic = "/imu/data", field = "angular_velocity.x" }}, got {table!r}')
    columns = tuple(_bag_column(name, entry, f"{in_columns} {name}") for name, entry in table.items())
    time_column = section.get("time_column", "t")
    if time_column in table:
        raise AttendInputError(f"{in_columns} {time_column}: the name of the log's time column ([log] time_column); "
                               "give the column another name")
    missing = [f"{name!r} ({named})" for name, named in used_columns.items() if name not in table]
    if missing:
        raise AttendInputError(f"{in_columns} has no entry for the column{'s' if len(missing) > 1 else ''} "
                               f"{', '.join(missing)}; expected name = {{ topic = \"/topic\", field = \"a.b\" }} for each "
                               "output and measured-input column")
    if "rate_hz" in section and "dt" in section:
        raise AttendInputError(f"{where}: give rate_hz or dt (the grid's rate or step), not both")
    dt = None
    if "rate_hz" in section:
        dt = 1.0 / _positive(section["rate_hz"], f"{where} rate_hz", "Hz")
    elif "dt" in section:
        dt = _positive(section["dt"], f"{where} dt", "seconds")
    if dt is not None and model_dt is not None and abs(dt - model_dt) > 1e-9 * model_dt:
        given_as = f"rate_hz = {section['rate_hz']} (dt {dt:.6g} s)" if "rate_hz" in section else f"dt = {dt:.6g} s"
        raise AttendInputError(f"{where} {given_as} but [model] dt = {model_dt:.6g} s; give one of them")
    grid_topic = section.get("grid_topic")
    if grid_topic is not None:
        grid_topic = _text(grid_topic, f"{where} grid_topic")
        topics = dict.fromkeys(column.topic for column in columns)
        if grid_topic not in topics:
            raise AttendInputError(f"{where} grid_topic: {grid_topic!r} is not a topic of [log.columns]; expected one of "
                                   f"{', '.join(map(repr, topics))}")
    for key, allowed in (("resample", RESAMPLE_RULES), ("stamps", STAMP_SOURCES)):
        if key in section and section[key] not in allowed:
            raise AttendInputError(f"{where} {key}: expected {' or '.join(map(repr, allowed))}, got {section[key]!r}")
    max_gap = _positive(section["max_gap"], f"{where} max_gap", "seconds") if "max_gap" in section else None
    return BagLayout(columns, dt if dt is not None else model_dt, grid_topic, section.get("resample", "linear"),
                     section.get("stamps", "auto"), max_gap)


def _positive(value, field: str, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise AttendInputError(f"{field}: expected a number > 0 ({unit}), got {value!r}")
    return float(value)


def _bag_column(name: str, entry, where: str) -> BagColumn:
    """One [log.columns] entry: { topic = "...", field = "a.b[0].c" }."""
    if not isinstance(entry, dict):
        raise AttendInputError(f'{where}: expected {{ topic = "/topic", field = "a.b" }}, got {entry!r}')
    unknown = sorted(set(entry) - {"topic", "field"})
    if unknown:
        raise AttendInputError(f"{where}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))}; "
                               "expected topic and field")
    for key in ("topic", "field"):
        if key not in entry:
            raise AttendInputError(f'{where}: needs {key} (expected {{ topic = "/topic", field = "a.b" }})')
    topic, field = _text(entry["topic"], f"{where} topic"), _text(entry["field"], f"{where} field")
    if not all(_SEGMENT.fullmatch(part) for part in field.split(".")):
        raise AttendInputError(f"{where} field: expected a path of field names separated by dots, each with an optional "
                               f"[index] from 0 (e.g. \"angular_velocity.x\", \"data[0]\"), got {field!r}")
    return BagColumn(name, topic, field)


def read_bag(path: str | Path, layout: BagLayout | None, time_column: str = "t", *, gaps: bool = False):
    """Read the bag at ``path`` as a :class:`~attend.io.Log` on one uniform grid (module docstring).

    path: a ROS 1 .bag, a ROS 2 bag folder or its .db3 file, or an .mcap file; layout: the topic and
    field of each column and the grid (the model file's [log] section, :func:`bag_layout`);
    time_column: the name of the log's time column [s from the first grid time]; gaps: True
    (`attend estimate`): grid times inside a dropout are missing values (NaN), False: an error.
    Errors name the file and the topic, field or key."""
    path = Path(path)
    if layout is None:
        raise AttendInputError(f"{path}: a ROS bag; reading it needs the model file's [log.columns] table (the topic and "
                               "field of each column, docs/command-line.md: ROS bags and MCAP files)")
    try:
        from rosbags.highlevel import AnyReader, AnyReaderError
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise AttendInputError(f'{path}: reading a ROS bag needs the rosbags package: pip install "attend[ros]"') from None
    if not path.exists():
        raise AttendInputError(f"log: {path} does not exist")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise AttendInputError(f"{path}: a folder without metadata.yaml; expected a ROS 2 bag folder, or its .db3 or "
                               ".mcap file")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except AnyReaderError as error:
        raise AttendInputError(f"{path}: not a readable ROS bag ({error})") from None
    except Exception as error:  # rosbags' parsers on a damaged file: not only their own errors
        raise AttendInputError(f"{path}: not a readable ROS bag ({type(error).__name__}: {error})") from None
    try:
        series, kinds, steps, start = _read_messages(reader, path, layout)
    finally:
        reader.close()
    return _resample(path, layout, series, kinds, steps, start, time_column, gaps)


def _read_messages(reader, path: Path, layout: BagLayout):
    """(series, kinds, steps, start): series[column] = (stamps [ns] int64, values) of each column,
    NaN values left out; kinds[topic] = "header" or "receive" (the stamps used); steps[topic] = the
    median interval of its messages [ns]; start = the bag's first message [ns]."""
    connections = {}
    for connection in reader.connections:
        connections.setdefault(connection.topic, []).append(connection)
    fielddefs = reader.typestore.fielddefs
    kinds, steps = {}, {}
    for topic in layout.topics:
        names = [column.name for column in layout.columns if column.topic == topic]
        if topic not in connections:
            present = ", ".join(f"{name} ({group[0].msgtype})" for name, group in sorted(connections.items()))
            raise AttendInputError(f"{path}: no topic {topic!r} (column{'s' if len(names) > 1 else ''} "
                                   f"{', '.join(names)} of [log.columns]); the bag has {present or 'no topics'}")
        types = sorted({connection.msgtype for connection in connections[topic]})
        if len(types) > 1:
            raise AttendInputError(f"{path}: topic {topic!r} carries several message types ({', '.join(types)}); "
                                   "expected one")
        msgtype = types[0]
        for column in layout.columns:
            if column.topic == topic:
                _check_field(fielddefs, msgtype, column, path)
        header = dict(fielddefs[msgtype][1]).get("header")
        has_header = header is not None and int(header[0]) == _NODE_NAME and header[1] == "std_msgs/msg/Header"
        if layout.stamps == "header" and not has_header:
            raise AttendInputError(f"{path}: topic {topic!r}: its messages ({msgtype}) have no header; [log] stamps = "
                                   "\"header\" needs one (\"auto\" uses the receive time of such topics)")
        kinds[topic] = "header" if has_header and layout.stamps != "receive" else "receive"
    wanted = [connection for topic in layout.topics for connection in connections[topic]]
    stamps = {topic: [] for topic in layout.topics}
    values = {column.name: [] for column in layout.columns}
    by_topic = {topic: [column for column in layout.columns if column.topic == topic] for topic in layout.topics}
    try:
        for connection, received, raw in reader.messages(connections=wanted):
            message = reader.deserialize(raw, connection.msgtype)
            topic = connection.topic
            if kinds[topic] == "header":
                stamp = message.header.stamp
                stamps[topic].append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec))
            else:
                stamps[topic].append(int(received))
            for column in by_topic[topic]:
                values[column.name].append(_field_value(message, column, len(stamps[topic]), path))
    except AttendInputError:
        raise
    except Exception as error:  # a damaged bag or message: rosbags' own errors
        raise AttendInputError(f"{path}: not a readable ROS bag ({type(error).__name__}: {error})") from None
    start = int(reader.start_time)
    series = {}
    for topic in layout.topics:
        columns = ", ".join(column.name for column in by_topic[topic])
        times = np.array(stamps[topic], dtype=np.int64)
        if len(times) < 2:
            count = "no messages" if len(times) == 0 else "1 message"
            raise AttendInputError(f"{path}: topic {topic!r} (column{'s' if len(by_topic[topic]) > 1 else ''} {columns}) "
                                   f"has {count}; expected at least 2 to resample")
        _check_increasing(times, path, topic, kinds[topic], start)
        steps[topic] = float(np.median(np.diff(times)))
        for column in by_topic[topic]:
            column_values = np.array(values[column.name], dtype=float)
            _check_values(column_values, times, column, path, start)
            kept = ~np.isnan(column_values)
            if kept.sum() < 2:
                raise AttendInputError(f"{path}: topic {topic!r}, field {column.field!r} (column {column.name!r}): "
                                       f"{'every value is' if not kept.any() else 'all values but one are'} NaN; "
                                       "expected at least 2 numbers")
            series[column.name] = (times[kept], column_values[kept])
    return series, kinds, steps, start


def _check_field(fielddefs: dict, msgtype: str, column: BagColumn, path: Path) -> None:
    """The column's field path exists in ``msgtype`` and ends in a number (an element of an array
    when it is one); errors name the topic, the field and what the type has instead."""
    where = f"{path}: topic {column.topic!r} ({msgtype}), field {column.field!r} (column {column.name!r})"
    current = msgtype
    steps = column.path
    for k, (name, index) in enumerate(steps):
        shown = ".".join(column.field.split(".")[:k + 1])  # the path so far, e.g. "poses[2]"
        array = ".".join(column.field.split(".")[:k] + [name])  # ... without the index, "poses"
        fields = dict(fielddefs[current][1])
        if name not in fields:
            raise AttendInputError(f"{where}: {current} has no field {name!r}; it has {', '.join(fields) or 'no fields'}")
        node = fields[name]
        kind, detail = int(node[0]), node[1]
        if kind in (_NODE_ARRAY, _NODE_SEQUENCE):
            element, length = detail
            if index is None:
                size = f"{length} " if kind == _NODE_ARRAY else ""
                raise AttendInputError(f"{where}: {array!r} is an array of {size}{_type_name(element)}; name one "
                                       f"element, e.g. \"{array}[0]\"")
            if kind == _NODE_ARRAY and index >= length:
                raise AttendInputError(f"{where}: {array!r} has {length} elements (indices 0..{length - 1}), got "
                                       f"index {index}")
            kind, detail = int(element[0]), element[1]
        elif index is not None:
            raise AttendInputError(f"{where}: {array!r} is not an array; remove [{index}]")
        last = k == len(steps) - 1
        if kind == _NODE_NAME:
            if last:
                nested = ", ".join(f"{shown}.{child}" for child, _ in fielddefs[detail][1])
                raise AttendInputError(f"{where}: {shown!r} is a {detail} message, not a number; name one of its "
                                       f"fields: {nested}")
            current = detail
        else:
            if not last:
                raise AttendInputError(f"{where}: {shown!r} is a {detail[0]}, it has no field "
                                       f"{steps[k + 1][0]!r}")
            if detail[0] in _TEXT_TYPES:
                raise AttendInputError(f"{where}: a {detail[0]}, not a number; expected a numeric field")


def _type_name(node) -> str:
    kind, detail = int(node[0]), node[1]
    return detail if kind == _NODE_NAME else detail[0] if kind == _NODE_BASE else "array"


def _field_value(message, column: BagColumn, number: int, path: Path) -> float:
    """The column's field of one message as a float (number: the message's count on its topic)."""
    value = message
    for name, index in column.path:
        value = getattr(value, name)
        if index is not None:
            if index >= len(value):
                raise AttendInputError(f"{path}: topic {column.topic!r}, message {number}: field {column.field!r} "
                                       f"(column {column.name!r}): {name!r} has {len(value)} elements, index {index} "
                                       "is beyond it")
            value = value[index]
    return float(value)


def _check_increasing(times: np.ndarray, path: Path, topic: str, kind: str, start: int) -> None:
    """Stamps strictly increase over a topic's messages (in the bag's order)."""
    steps = np.diff(times)
    if np.all(steps > 0):
        return
    bad = int(np.argmax(steps <= 0)) + 1
    how = "repeats the previous one" if steps[bad - 1] == 0 else "goes backwards"
    hint = (" ([log] stamps = \"receive\" uses the bag's receive times instead)" if kind == "header" else "")
    raise AttendInputError(
        f"{path}: topic {topic!r}: the {kind} stamp of message {bad + 1} ({_seconds(times[bad], start)}) {how} "
        f"(message {bad}: {_seconds(times[bad - 1], start)}); expected increasing time stamps{hint}")


def _check_values(values: np.ndarray, times: np.ndarray, column: BagColumn, path: Path, start: int) -> None:
    """inf and values beyond +-1e150 are errors naming the topic, field and message (NaN: missing)."""
    bad = np.isinf(values) | (np.abs(np.nan_to_num(values)) > LARGEST_MAGNITUDE)
    if bad.any():
        k = int(np.argmax(bad))
        expected = "a finite number" if np.isinf(values[k]) else f"a value within +-{LARGEST_MAGNITUDE:.0e}"
        raise AttendInputError(f"{path}: topic {column.topic!r}, message {k + 1} ({_seconds(times[k], start)}), field "
                               f"{column.field!r} (column {column.name!r}): expected {expected}, got {values[k]:.6g}")


def _seconds(stamp: int, start: int) -> str:
    """A stamp [ns] as seconds from the bag's first message."""
    return f"t = {(int(stamp) - start) / 1e9:.6g} s into the bag"


def _resample(path: Path, layout: BagLayout, series: dict, kinds: dict, steps: dict, start: int, time_column: str,
              gaps: bool):
    """The columns on the uniform grid (module docstring) as a Log (arguments: :func:`_read_messages`)."""
    from attend.io.logs import Log

    fastest = min(layout.topics, key=lambda topic: steps[topic])
    grid_topic = layout.grid_topic or fastest
    step = layout.dt * 1e9 if layout.dt is not None else steps[grid_topic]
    if step < (1 - RATE_TOLERANCE) * steps[fastest]:
        given = "[log] rate_hz or dt, or [model] dt" if layout.dt is not None else "the grid topic's rate"
        raise AttendInputError(
            f"{path}: a grid every {step / 1e9:.6g} s ({1e9 / step:.6g} Hz, {given}) is faster than every topic named in "
            f"[log.columns]: the fastest, {fastest!r}, has a message every {steps[fastest] / 1e9:.6g} s "
            f"({1e9 / steps[fastest]:.6g} Hz); a grid finer than the data invents samples: use rate_hz <= "
            f"{1e9 / steps[fastest]:.6g}")
    first = max(int(times[0]) for times, _ in series.values())
    last = min(int(times[-1]) for times, _ in series.values())
    spans = "; ".join(f"{column.name} ({column.topic}): {_seconds(series[column.name][0][0], start)} to "
                      f"{(int(series[column.name][0][-1]) - start) / 1e9:.6g} s" for column in layout.columns)
    topic_times = np.concatenate([series[column.name][0] for column in layout.columns if column.topic == grid_topic])
    topic_times = np.unique(topic_times)
    inside = topic_times[(topic_times >= first) & (topic_times <= last)]
    count = 0 if not len(inside) else int(math.floor((last - int(inside[0])) / step)) + 1
    if count < 2:
        raise AttendInputError(f"{path}: the topics have no common span of 2 grid samples (a step of {step / 1e9:.6g} s "
                               f"starting at a message of {grid_topic!r}); they cover {spans}")
    origin = int(inside[0])
    grid = origin + np.rint(np.arange(count) * step).astype(np.int64)
    grid = grid[grid <= last]
    columns = {time_column: (grid - origin) / 1e9}
    dropouts = []
    for column in layout.columns:
        times, values = series[column.name]
        max_gap = layout.max_gap * 1e9 if layout.max_gap is not None else GAP_INTERVALS * steps[column.topic]
        resampled, missing = _on_grid(times, values, grid, layout.resample, max_gap)
        if missing.any():
            k = int(np.argmax(missing))
            j = int(np.searchsorted(times, grid[k], side="right")) - 1
            silence = (int(times[j + 1]) - int(times[j])) / 1e9
            limit = f"[log] max_gap = {layout.max_gap:g} s" if layout.max_gap is not None else \
                f"{GAP_INTERVALS:g} of its {steps[column.topic] / 1e9:.6g} s intervals; [log] max_gap sets it"
            where = (f"topic {column.topic!r}, field {column.field!r} (column {column.name!r}): no message for "
                     f"{silence:.6g} s from {_seconds(times[j], start)} (longer than {limit})")
            if not gaps:
                raise AttendInputError(f"{path}: {where}: {int(missing.sum())} grid samples from t = {columns[time_column][k]:.6g} s "
                                       "would be invented; cut the bag, or estimate with the gaps (`attend estimate`)")
            dropouts.append(f"{column.name}: {int(missing.sum())} missing")
        columns[column.name] = resampled
    rule = "linear interpolation" if layout.resample == "linear" else "sample-and-hold"
    stamp_kinds = ", ".join(f"{topic} {kinds[topic]}" for topic in layout.topics)
    origin_text = (f"{_bag_kind(path)}: {len(grid)} samples every {step / 1e9:.6g} s ({1e9 / step:.6g} Hz) from "
                   f"{_seconds(origin, start)} (bag time {origin // 10**9}.{origin % 10**9:09d} s, a message of {grid_topic}), {rule}; "
                   f"stamps: {stamp_kinds}" + (f"; dropouts: {', '.join(dropouts)}" if dropouts else ""))
    return Log(columns[time_column], columns, str(path), None, origin_text)


def _on_grid(times: np.ndarray, values: np.ndarray, grid: np.ndarray, rule: str, max_gap: float):
    """(values at the grid times, missing): "linear" or "hold" between the messages (times [ns],
    values) around each grid time; missing: grid times strictly inside a silence longer than
    max_gap [ns], set to NaN."""
    j = np.searchsorted(times, grid, side="right") - 1  # times[j] <= grid < times[j + 1]
    at_end = j >= len(times) - 1
    following = np.minimum(j + 1, len(times) - 1)
    interval = (times[following] - times[j]).astype(float)
    offset = (grid - times[j]).astype(float)
    if rule == "hold":
        resampled = values[j].copy()
    else:
        weight = np.where(at_end, 0.0, offset / np.where(at_end, 1.0, interval))
        resampled = values[j] + weight * (values[following] - values[j])
    missing = ~at_end & (interval > max_gap) & (offset > 0)
    resampled[missing] = np.nan
    return resampled, missing


def _bag_kind(path: Path) -> str:
    if path.is_dir():
        return "ROS 2 bag"
    return {".bag": "ROS 1 bag", ".mcap": "MCAP file", ".db3": "ROS 2 bag (sqlite3)"}.get(path.suffix.lower(), "bag")
