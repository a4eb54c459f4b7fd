"""
Tolerant scanning of MCAP files, record by record.

:func:`scan_mcap` walks the records of a file that may lack its summary and
footer (a recording cut short by a crash) and reports what it holds and
where it stops.
"""

from dataclasses import dataclass
import io
import os

from gyro_emulator.recording.mcap_writer import MCAP_MAGIC, RECORD_HEAD
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk

_VALID_OPCODES = frozenset(int(op) for op in Opcode)


@dataclass
class ScanReport:
    """
    What a sequential scan of one MCAP file found.

    Attributes
    ----------
    path : str
        The file.
    size_bytes : int
        File size.
    good_bytes : int
        Bytes up to the end of the last intact record.
    complete : bool
        A footer and closing magic were found.
    data_end : bool
        The data section ended cleanly (everything after it is summary).
    problem : str or None
        Why the scan stopped early, if it did.
    messages : int
        Messages recovered.
    bad_chunks : int
        Chunks skipped because they failed to decompress or their CRC.
    last_log_time_ns : int or None
        Log time of the last recovered message.

    """

    path: str
    size_bytes: int = 0
    good_bytes: int = 0
    complete: bool = False
    data_end: bool = False
    problem: str = None
    messages: int = 0
    bad_chunks: int = 0
    last_log_time_ns: int = None

    def describe(self):
        """Return a one-line human summary."""
        if self.complete and not self.problem:
            return f'{self.path}: complete, {self.messages} messages'
        state = 'data section intact, summary missing' if self.data_end else (
            self.problem or 'incomplete')
        lost = self.size_bytes - self.good_bytes
        return (f'{self.path}: {state}; recovered {self.messages} messages'
                f'{f", skipped {self.bad_chunks} corrupt chunks" if self.bad_chunks else ""}'
                f'{f", discarded {lost} trailing bytes" if lost > 0 else ""}')


def _parse_record(opcode, body):
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.MESSAGE:
        return Message.read(stream, len(body))
    reader = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.CHUNK: Chunk,
              Opcode.METADATA: Metadata, Opcode.HEADER: Header,
              Opcode.FOOTER: Footer, Opcode.DATA_END: DataEnd}.get(opcode)
    return reader.read(stream) if reader else None


def scan_mcap(path, report=None):
    """
    Yield the Schema, Channel, Message and Metadata records of an MCAP file.

    Reads sequentially and tolerates what a killed writer leaves: a missing
    summary, footer or magic, or a truncated final record. A chunk that fails
    to decompress or whose CRC does not match is skipped and counted; an
    unknown opcode or a length running past the end stops the scan. The
    outcome is recorded in ``report`` (a :class:`ScanReport`).

    Parameters
    ----------
    path : str
        MCAP file.
    report : ScanReport, optional
        Filled in as the scan proceeds.

    Raises
    ------
    ValueError
        If the file does not start with the MCAP magic.

    """
    report = report if report is not None else ScanReport(path)
    report.path = path
    with open(path, 'rb') as handle:
        size = os.fstat(handle.fileno()).st_size
        report.size_bytes = size
        magic = handle.read(len(MCAP_MAGIC))
        if len(magic) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(magic):
            report.problem = f'the file is truncated to {size} bytes, before any record'
            return
        if magic != MCAP_MAGIC:
            raise ValueError(f'{path} is not an MCAP file (it does not start with the '
                             f'MCAP magic; {size} bytes)')
        position = len(MCAP_MAGIC)
        report.good_bytes = position
        while True:
            head = handle.read(9)
            if not head:
                report.problem = report.problem or 'the file ends without a footer'
                return
            if len(head) < 9:
                report.problem = f'truncated record header at byte {position}'
                return
            opcode, length = RECORD_HEAD.unpack(head)
            if opcode not in _VALID_OPCODES:
                report.problem = f'corrupt record (opcode 0x{opcode:02x}) at byte {position}'
                return
            if length > size - position - 9:
                name = Opcode(opcode).name.lower()
                report.problem = (f'truncated {name} record at byte {position} '
                                  f'({size - position - 9} of {length} bytes present)')
                return
            body = handle.read(length)
            try:
                record = _parse_record(opcode, body)
                inner = breakup_chunk(record, validate_crc=True) \
                    if opcode == Opcode.CHUNK else None
            except Exception as exc:  # noqa: B902 - any decoder error means corrupt data
                if opcode == Opcode.CHUNK:
                    report.bad_chunks += 1
                    report.problem = (f'corrupt chunk at byte {position} skipped '
                                      f'({type(exc).__name__}: {exc})')
                    position += 9 + length
                    continue
                report.problem = (f'corrupt {Opcode(opcode).name.lower()} record at byte '
                                  f'{position} ({type(exc).__name__}: {exc})')
                return
            position += 9 + length
            report.good_bytes = position
            if opcode == Opcode.FOOTER:
                report.complete = handle.read(len(MCAP_MAGIC)) == MCAP_MAGIC
                if report.complete:
                    report.good_bytes = size
                else:
                    report.problem = 'the closing magic after the footer is missing'
                return
            if opcode == Opcode.DATA_END:
                report.data_end = True
                continue
            if report.data_end:
                continue        # summary section: repeated schemas/channels, indexes
            for item in (inner if inner is not None else (record,)):
                if isinstance(item, Message):
                    report.messages += 1
                    report.last_log_time_ns = item.log_time
                if isinstance(item, (Schema, Channel, Message, Metadata)):
                    yield item
