"""A hopper log as MCAP: channel `/hopper/signals`, one message per block of samples (README, "Logs in").

Each message is a `hopper_msgs/msg/SignalBlock` (schema encoding `ros2msg`, message encoding
`cdr`, so ROS 2 tools and Foxglove decode it too):

    string[] names    # the columns (hopper.logs.schema), "time" first
    string[] units    # each column's unit: its SI unit, or one the schema converts (deg, rpm, ...)
    uint32 samples    # n, the samples in this block
    float64[] values  # column-major, len(names) * n: values[k * n + i] is column k at sample i

A block is BLOCK_SAMPLES samples (1 s at 1 kHz); its log time is its first sample's. The
channel's metadata `source` says what the log was written from (the reader's Log.source keeps it), and
`world.terrain`, `world.seed`, `world.gravity` (and `world.model`) where it was recorded, when the log
knows (hopper.logs.world). The raw
float arrays make a 1-hour log 3,600 messages, decoded with one numpy view each. Messages are
read in file order, one chunk at a time, so a file whose time goes backwards is refused rather
than silently sorted, and memory stays near one copy of the log.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import zstandard
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, Writer

from hopper.logs.columns import Columns
from hopper.logs.schema import COLUMNS, Log, LogError, check_columns, located, to_si
from hopper.logs.world import World, from_meta

TOPIC = "/hopper/signals"
WORLD = "world."  # prefix of the channel metadata keys of the log's world
SCHEMA_NAME = "hopper_msgs/msg/SignalBlock"
SCHEMA_TEXT = """\
# A block of consecutive samples of a hopper log (hopper-dashboard README, "Logs in").
string[] names    # the columns (hopper.logs.schema), "time" first
string[] units    # each column's unit: its SI unit, or one the schema converts (deg, deg/s, rpm, ms, Nm)
uint32 samples    # n, the samples in this block
float64[] values  # column-major, len(names) * n: values[k * n + i] is column k at sample i
"""
BLOCK_SAMPLES = 1000
CDR_LE = b"\x00\x01\x00\x00"  # CDR encapsulation header: plain CDR, little-endian


class _Bad(LogError):
    """A message that is not a SignalBlock (caught and re-raised as a LogError that says where)."""


def encode(names: list[str], units: list[str], values: np.ndarray) -> bytes:
    """One SignalBlock in CDR: `values` is (len(names), n) float64."""
    out = bytearray(CDR_LE)

    def align(size: int) -> None:  # CDR aligns each primitive to its size, from after the header
        out.extend(b"\0" * (-(len(out) - len(CDR_LE)) % size))

    for strings in (names, units):
        align(4)
        out += struct.pack("<I", len(strings))
        for text in strings:
            align(4)
            data = text.encode() + b"\0"
            out += struct.pack("<I", len(data)) + data
    align(4)
    out += struct.pack("<II", values.shape[1], values.size)
    align(8)
    out += np.ascontiguousarray(values, dtype="<f8").tobytes()
    return bytes(out)


def decode(data: bytes) -> tuple[list[str], list[str], np.ndarray]:
    """(names, units, values (len(names), n)) of one SignalBlock; _Bad saying why it is not one."""
    if data[:4] != CDR_LE:
        raise _Bad("not little-endian CDR")
    at = 4

    def take(size: int, count: int = 1) -> tuple:
        nonlocal at
        at += -(at - 4) % size
        fmt = {4: "I", 8: "d"}[size]
        values = struct.unpack_from(f"<{count}{fmt}", data, at)
        at += size * count
        return values

    try:
        strings: list[list[str]] = []
        for _ in range(2):
            (count,) = take(4)
            texts = []
            for _ in range(count):
                (length,) = take(4)
                texts.append(data[at : at + length - 1].decode())
                at += length
            strings.append(texts)
        samples, size = take(4, 2)
        at += -(at - 4) % 8
        names, units = strings
        if len(units) != len(names) or size != len(names) * samples or at + 8 * size > len(data):
            raise _Bad(f"{len(names)} names, {len(units)} units, {samples} samples but {size} values")
        values = np.frombuffer(data, dtype="<f8", count=size, offset=at).reshape(len(names), samples)
    except (struct.error, UnicodeDecodeError, ValueError) as exc:
        raise _Bad(f"cut short or garbled ({exc})") from None
    return names, units, values


def write(log: Log, path: str | Path) -> Path:
    """Write `log` as MCAP (SI units, zstd chunks); returns the path."""
    path = Path(path)
    names = ["time", *log.signals]
    units = [COLUMNS[n].unit for n in names]
    columns = np.stack([log.time, *log.signals.values()])
    with path.open("wb") as f:
        writer = Writer(f, chunk_size=4 << 20, compression=CompressionType.ZSTD)
        writer.start(profile="", library="hopper-dashboard")
        schema = writer.register_schema(SCHEMA_NAME, "ros2msg", SCHEMA_TEXT.encode())
        world = {f"{WORLD}{k}": v for k, v in log.world.to_meta().items()} if log.world is not None else {}
        channel = writer.register_channel(TOPIC, "cdr", schema, metadata={"source": log.source, **world})
        for start in range(0, len(log.time), BLOCK_SAMPLES):
            block = columns[:, start : start + BLOCK_SAMPLES]
            stamp = max(0, round(float(block[0, 0]) * 1e9))
            writer.add_message(channel, log_time=stamp, data=encode(names, units, block), publish_time=stamp)
        writer.finish()
    return path


def _channel(reader, path: Path) -> tuple[int, int, str, World | None]:  # noqa: ANN001 (mcap's McapReader)
    """The /hopper/signals channel's id, message count, `source` (what the log was written from) and
    world (None if it has none); LogError if there is no such channel, or its world is bad."""
    summary = reader.get_summary()
    if summary is None:
        raise LogError(f"{path}: an MCAP file without its summary (not finished?); write it again")
    channels = [c for c in summary.channels.values() if c.topic == TOPIC]
    if not channels:
        topics = ", ".join(sorted(c.topic for c in summary.channels.values())) or "none"
        raise LogError(f"{path}: no {TOPIC} channel (its channels: {topics})")
    channel = channels[0]
    schema = summary.schemas.get(channel.schema_id)
    if schema is None or schema.name != SCHEMA_NAME or channel.message_encoding != "cdr":
        got = f"{schema.name if schema else 'no schema'} in {channel.message_encoding or 'no encoding'}"
        raise LogError(f"{path}: {TOPIC} carries {got}, expected {SCHEMA_NAME} in cdr")
    count = summary.statistics.channel_message_counts.get(channel.id, 0) if summary.statistics else 0
    meta = {k.removeprefix(WORLD): v for k, v in channel.metadata.items() if k.startswith(WORLD)}
    try:
        world = from_meta(meta) if meta else None
    except ValueError as exc:
        raise LogError(f"{path}: {TOPIC}'s metadata: {exc}") from None
    return channel.id, count, channel.metadata.get("source", ""), world


def read(path: str | Path) -> Log:
    """The MCAP log at `path`, in SI units, its gaps marked; LogError with what and where otherwise."""
    path = Path(path)
    if path.stat().st_size == 0:
        raise LogError(f"{path}: empty file (not an MCAP log)")
    data: Columns | None = None
    first: list[str] = []
    starts: list[int] = []  # each message's first sample, to say where a bad sample is
    with path.open("rb") as f:
        try:
            channel, count, origin, world = _channel(make_reader(f), path)
            # Then one pass in file order, a chunk in memory at a time (the seeking reader's file
            # order decompresses every chunk before it yields the first message).
            f.seek(0)
            messages = NonSeekingReader(f).iter_messages(topics=[TOPIC], log_time_order=False)
            for m, (_, _, message) in enumerate(messages):
                if message.channel_id != channel:
                    continue
                try:
                    names, units, values = decode(message.data)
                except _Bad as exc:
                    raise LogError(f"{path}: {TOPIC} message {m} is not a {SCHEMA_NAME}: {exc}") from None
                if data is None:
                    check_columns(names, f"{path}: {TOPIC} message 0")
                    first = names
                    factors = [to_si(n, u, f"{path}: {TOPIC}") for n, u in zip(names, units, strict=True)]
                    data = Columns(names, int(1.05 * max(1, count) * values.shape[1]) + 16)
                elif names != first:
                    raise LogError(f"{path}: {TOPIC} message {m} has columns {names}, message 0 {first}")
                starts.append(data.n)
                data.append({n: v * k if k != 1.0 else v for n, v, k in zip(names, values, factors, strict=True)})
        except LogError:
            raise
        except (
            McapError,
            zstandard.ZstdError,
            struct.error,
            ValueError,
            EOFError,
        ) as exc:  # mcap's reader on a foreign or torn file
            why = str(exc) or type(exc).__name__
            raise LogError(f"{path}: not an MCAP file, or one cut short or damaged ({why})") from None
    if data is None:
        raise LogError(f"{path}: {TOPIC} has no messages")
    signals = {name: data.take(name) for name in first}
    time = signals.pop("time")

    def where(sample: int) -> str:
        m = int(np.searchsorted(starts, sample, side="right")) - 1
        return f"{TOPIC} message {m}, its sample {sample - starts[m]}"

    source = f"{path} (written from {origin})" if origin and origin != str(path) else str(path)
    return located(time, signals, source, where, world)
