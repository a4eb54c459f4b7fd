"""
Recovery of bags cut short by a crash.

:func:`repair_bag` rewrites such a bag whole, with a summary, a footer and
a ``metadata.yaml``.
"""

from dataclasses import dataclass, field
import os
import shutil

from gyro_emulator.recording.mcap_writer import McapFileWriter
from gyro_emulator.recording.metadata import (file_info_from_writer, METADATA_FILE, metadata_yaml,
                                              write_text_atomic)
from gyro_emulator.recording.reader import BagReader, index_file, resolve_files
from gyro_emulator.recording.scan import scan_mcap, ScanReport
from mcap.records import Channel, Message, Metadata, Schema


@dataclass
class RepairReport:
    """
    What :func:`repair_bag` did.

    Attributes
    ----------
    bag_dir : str
        The repaired bag directory.
    scans : list of ScanReport
        One per MCAP file.
    rewritten : list of str
        Files rewritten from recovered records.
    backups : list of str
        Originals kept beside the repaired files.
    topics : dict of str to int
        Messages per topic in the repaired bag.
    start_time_ns, end_time_ns : int
        Span of the recovered messages, ns.
    corrupt : list of dict
        Chunks of otherwise complete files that failed their CRC or could not
        be decompressed (``BagReader.corrupt_chunks`` entries: file, byte
        offset, log-time range, reason); those files are rewritten without them.
    lost_messages : int
        Messages of those chunks, lost.

    """

    bag_dir: str
    scans: list = field(default_factory=list)
    rewritten: list = field(default_factory=list)
    backups: list = field(default_factory=list)
    topics: dict = field(default_factory=dict)
    start_time_ns: int = 0
    end_time_ns: int = 0
    corrupt: list = field(default_factory=list)
    lost_messages: int = 0

    @property
    def message_count(self):
        """Return the total recovered messages."""
        return sum(self.topics.values())

    def describe(self):
        """Return a human summary, one line per file and per topic."""
        lines = [s.describe() for s in self.scans]
        for chunk in self.corrupt:
            lines.append(f'{chunk["file"]}: corrupt chunk at byte {chunk["offset"]} (log time '
                         f'{chunk["start_ns"]}..{chunk["end_ns"]} ns, {chunk["reason"]}) dropped')
        if self.corrupt:
            lines.append(f'{self.lost_messages} messages lost in {len(self.corrupt)} '
                         'corrupt chunk(s)')
        if self.rewritten:
            lines.append('rewrote ' + ', '.join(os.path.basename(p) for p in self.rewritten)
                         + ' with summary and footer')
        for path in self.backups:
            lines.append(f'kept the original as {os.path.basename(path)}')
        for name in sorted(self.topics):
            lines.append(f'  {name}: {self.topics[name]} messages')
        span = (self.end_time_ns - self.start_time_ns) / 1e9
        lines.append(f'{self.message_count} messages over {span:.3f} s; wrote '
                     f'{os.path.join(self.bag_dir, METADATA_FILE)}')
        return '\n'.join(lines)


def _rewrite(source, target, compression):
    """Copy the recovered records of ``source`` into a complete file ``target``."""
    report = ScanReport(source)
    writer = McapFileWriter(target, compression=compression, flush_interval_s=3600.0)
    schema_ids, channel_ids, custom = {}, {}, {}
    try:
        for record in scan_mcap(source, report):
            if isinstance(record, Message):
                cid = channel_ids.get(record.channel_id)
                if cid is not None:
                    writer.write(cid, record.data, record.log_time, record.publish_time,
                                 record.sequence)
            elif isinstance(record, Schema):
                if record.id not in schema_ids:
                    schema_ids[record.id] = writer.add_schema(record.name, record.data,
                                                              record.encoding)
            elif isinstance(record, Channel):
                if record.id not in channel_ids and record.schema_id in schema_ids:
                    channel_ids[record.id] = writer.add_channel(
                        record.topic, schema_ids[record.schema_id], record.metadata,
                        record.message_encoding)
            elif isinstance(record, Metadata) and record.name == 'gyro_emulator':
                custom = dict(record.metadata)
                writer.add_metadata(record.name, record.metadata)
    finally:
        writer.finish()
    info = file_info_from_writer(writer)
    info.custom_data = custom
    return report, info


def repair_bag(path, out_dir=None, backup=True, compression='zstd'):
    """
    Make a bag whole again after its recorder was killed.

    Every MCAP file without a valid summary and footer is scanned
    (:func:`scan_mcap`) and rewritten with all recovered messages; then
    ``metadata.yaml`` is regenerated from the files. A complete bag only gets
    its ``metadata.yaml`` rewritten.

    Parameters
    ----------
    path : str
        Bag directory (or one .mcap file).
    out_dir : str, optional
        Write the repaired bag here instead of in place (must not exist).
    backup : bool
        In place, keep each rewritten original as ``<file>.orig``.
    compression : str
        Chunk compression of rewritten files.

    Returns
    -------
    RepairReport

    Raises
    ------
    ValueError
        If a file is not MCAP at all (bad magic).

    """
    bag_dir, files, meta = resolve_files(path)
    if out_dir is not None:
        out_dir = os.path.abspath(out_dir)
        if os.path.exists(out_dir) and os.listdir(out_dir):
            raise FileExistsError(f'output directory {out_dir} exists and is not empty')
        os.makedirs(out_dir, exist_ok=True)
    target_dir = out_dir or bag_dir
    report = RepairReport(target_dir)
    infos = []
    custom = dict((meta or {}).get('custom_data') or {})
    for source in files:
        target = os.path.join(target_dir, os.path.basename(source))
        try:
            info = index_file(source, tolerant=False)
        except ValueError:
            info = None
        if info is not None:
            corrupt, lost = BagReader(source).verify()
            if corrupt:
                report.corrupt.extend(corrupt)
                report.lost_messages += lost
                info = None             # rewrite it without the corrupt chunks
        if info is not None:
            scan = ScanReport(source, size_bytes=os.path.getsize(source),
                              good_bytes=os.path.getsize(source), complete=True,
                              messages=info.message_count)
            if target != source:
                shutil.copyfile(source, target)
                info.path = target
            report.scans.append(scan)
        else:
            tmp = target + '.repair-tmp'
            scan, info = _rewrite(source, tmp, compression)
            report.scans.append(scan)
            if target == source and backup:
                os.replace(source, source + '.orig')
                report.backups.append(source + '.orig')
            os.replace(tmp, target)
            info.path = target
            report.rewritten.append(target)
        for key, value in info.custom_data.items():
            custom.setdefault(key, value)
        infos.append(info)
    for info in infos:
        for name, topic in info.topics.items():
            report.topics[name] = report.topics.get(name, 0) + topic.message_count
    counted = [i for i in infos if i.message_count]
    report.start_time_ns = min((i.start_time_ns for i in counted), default=0)
    report.end_time_ns = max((i.end_time_ns for i in counted), default=0)
    write_text_atomic(os.path.join(target_dir, METADATA_FILE),
                      metadata_yaml(target_dir, infos, custom))
    return report
