"""
Recovery of bags cut short by a crash.

:func:`repair_bag` rewrites such a bag whole, with a summary, a footer and
a ``metadata.yaml``.

Copies and ``metadata.yaml`` are atomic writes
(:func:`gyro_emulator.atomic.staged`). A rewritten MCAP file is the one
exception that renames by itself (``os.replace``, here and in
:mod:`gyro_emulator.atomic` only): it is finished under the fixed name
``<file>.repair-tmp``, which :func:`gyro_emulator.recording.files.resolve_bag`
recognises, so a repair interrupted between its steps can be resumed and
never leaves the bag without its file.
"""

from dataclasses import dataclass, field
import os
import shutil

from gyro_emulator import atomic
from gyro_emulator.recording.files import (BACKUP, metadata_disagreements, REPAIR_TMP,
                                           resolve_bag)
from gyro_emulator.recording.mcap_writer import McapFileWriter
from gyro_emulator.recording.metadata import file_info_from_writer, METADATA_FILE, metadata_yaml
from gyro_emulator.recording.reader import BagReader, index_file
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
        Messages the file counted (its summary, else ``metadata.yaml``) that
        could not be recovered: those of the corrupt chunks, or of chunks
        whose header was destroyed.
    notes : list of str
        What else was found and done (a file listed twice, a malformed
        ``metadata.yaml`` replaced, a file restored after an interrupted repair).
    metadata_kept : bool
        The bag was sound (no file rewritten, ``metadata.yaml`` agreeing with
        the files): its ``metadata.yaml`` was left as it was (``out_dir``:
        copied byte for byte).

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
    notes: list = field(default_factory=list)
    metadata_kept: bool = False

    @property
    def message_count(self):
        """Return the total recovered messages."""
        return sum(self.topics.values())

    def describe(self):
        """Return a human summary, one line per file and per topic."""
        lines = list(self.notes) + [s.describe() for s in self.scans]
        for chunk in self.corrupt:
            lines.append(f'{chunk["file"]}: corrupt chunk at byte {chunk["offset"]} (log time '
                         f'{chunk["start_ns"]}..{chunk["end_ns"]} ns, {chunk["reason"]}) dropped')
        if self.lost_messages or self.corrupt:
            lines.append(f'{self.lost_messages} messages lost'
                         f'{f" in {len(self.corrupt)} corrupt chunk(s)" if self.corrupt else ""}'
                         ': the file counted them, no intact chunk holds them')
        if self.rewritten:
            lines.append('rewrote ' + ', '.join(os.path.basename(p) for p in self.rewritten)
                         + ' with summary and footer')
        for path in self.backups:
            lines.append(f'kept the original as {os.path.basename(path)}')
        for name in sorted(self.topics):
            lines.append(f'  {name}: {self.topics[name]} messages')
        span = (self.end_time_ns - self.start_time_ns) / 1e9
        meta = os.path.join(self.bag_dir, METADATA_FILE)
        lines.append(f'{self.message_count} messages over {span:.3f} s; ' + (
            f'the bag is sound: {meta} agrees with the files, kept byte for byte'
            if self.metadata_kept else f'wrote {meta}'))
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
        writer.finish()
    except BaseException:
        _discard(writer, target)
        raise
    info = file_info_from_writer(writer)
    info.custom_data = custom
    return report, info


def _discard(writer, path):
    """Close a failed writer and remove its file (a full disk, a file size limit)."""
    writer.abort()
    try:
        os.remove(path)
    except OSError:
        pass


def _keep_original(source):
    """Keep ``source`` as ``<source>.orig`` without ever leaving the bag without ``source``."""
    backup = source + BACKUP
    if os.path.exists(backup):
        return None                 # an earlier repair's backup: the older original
    try:
        os.link(source, backup)     # atomic; source stays in place
    except OSError:
        with atomic.staged(backup) as tmp:
            shutil.copy2(source, tmp)
    return backup


def _restore(full, stand_in, report):
    """Put back ``full`` from what an interrupted repair left (its finished temp or original)."""
    if stand_in.endswith(REPAIR_TMP):
        os.replace(stand_in, full)
    else:
        with atomic.staged(full) as tmp:
            shutil.copy2(stand_in, tmp)
    report.notes.append(f'{os.path.basename(full)} was missing after an interrupted repair: '
                        f'restored it from {os.path.basename(stand_in)}')


def _counted(meta, source, bag_dir):
    """Return the message count ``metadata.yaml`` gives ``source``, or None."""
    for item in (meta or {}).get('files') or ():
        if item.get('path') == os.path.relpath(source, bag_dir) and isinstance(
                item.get('message_count'), int) and not isinstance(item['message_count'], bool):
            return item['message_count']
    return None


def _needs_rewrite(source, report):
    """Return (FileInfo or None, messages its summary counts or None); None means rewrite."""
    try:
        info = index_file(source, tolerant=False)
    except ValueError:
        return None, None
    reader = BagReader(source)
    corrupt, lost = reader.verify()
    if corrupt or lost or reader.repeated_messages:
        report.corrupt.extend(corrupt)
        return None, info.message_count
    return info, info.message_count


def _repair_file(source, target, backup, compression, expected, report):
    """Repair one MCAP file into ``target``; return its FileInfo."""
    info, counted = _needs_rewrite(source, report)
    if info is not None:
        scan = ScanReport(source, size_bytes=os.path.getsize(source),
                          good_bytes=os.path.getsize(source), complete=True,
                          messages=info.message_count)
        if target != source:
            with atomic.staged(target) as tmp:
                shutil.copyfile(source, tmp)
            info.path = target
        elif os.path.exists(source + REPAIR_TMP):
            os.remove(source + REPAIR_TMP)
        report.scans.append(scan)
        return info
    tmp = target + REPAIR_TMP
    scan, info = _rewrite(source, tmp, compression)
    report.scans.append(scan)
    counted = counted if counted is not None else expected
    if counted is not None and counted > scan.messages + scan.repeated_messages:
        report.lost_messages += counted - scan.messages - scan.repeated_messages
    if target == source and backup:
        kept = _keep_original(source)
        if kept:
            report.backups.append(kept)
    os.replace(tmp, target)
    info.path = target
    report.rewritten.append(target)
    return info


def repair_bag(path, out_dir=None, backup=True, compression='zstd'):
    """
    Make a bag whole again after its recorder was killed, or after damage.

    Every MCAP file without a trustworthy summary and footer (missing,
    failing its CRC, or counting messages no intact chunk holds) is scanned
    (:func:`scan_mcap`: corrupt chunks skipped, repeated chunks dropped) and
    rewritten with all recovered messages; then ``metadata.yaml`` is
    regenerated from the files when it is missing, malformed or disagrees
    with them (:func:`_stale_metadata`). A sound bag is left byte for byte as
    it was (``out_dir``: copied as it is).

    The bag always has each of its files: the original is kept as
    ``<file>.orig`` by a hard link before the finished ``<file>.repair-tmp``
    replaces it, and a temporary file is removed when writing fails (a full
    disk, ``ulimit -f``). A file missing after an interrupted repair of an
    older version is restored from its ``.repair-tmp`` (when finished) or
    ``.orig`` first.

    Parameters
    ----------
    path : str
        Bag directory (or one .mcap file; in place, one of a bag's files
        repairs that bag).
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
    if out_dir is None:
        path = _bag_of(path)
    found = resolve_bag(path, metadata_errors='ignore')
    if out_dir is None:
        return _repair_into(found, found.bag_dir, None, backup, compression)
    out_dir = os.path.abspath(out_dir)
    if os.path.exists(out_dir) and os.listdir(out_dir):
        raise FileExistsError(f'output directory {out_dir} exists and is not empty')
    os.makedirs(os.path.dirname(out_dir), exist_ok=True)
    with atomic.staged(out_dir) as staging:     # the repaired bag is complete or absent
        os.makedirs(staging)
        report = _repair_into(found, staging, out_dir, backup, compression)
        if os.path.isdir(out_dir):
            os.rmdir(out_dir)                   # the empty directory it replaces
    report.bag_dir = out_dir
    report.rewritten = [os.path.join(out_dir, os.path.basename(p)) for p in report.rewritten]
    return report


def _bag_of(path):
    """
    Return what an in-place repair of ``path`` repairs: a file's bag when it has one.

    The ``metadata.yaml`` beside an ``.mcap`` file is that bag's: a repair
    regenerating it from the one file would drop the bag's other files and
    what it says of them. A file it lists is repaired as its bag (every file,
    one ``metadata.yaml``); a file it does not list is refused in one line.
    """
    full = os.path.abspath(path)
    bag_dir = os.path.dirname(full)
    if not os.path.isfile(full) or os.path.basename(full) == METADATA_FILE or \
            not os.path.isfile(os.path.join(bag_dir, METADATA_FILE)):
        return path
    if full in resolve_bag(bag_dir, metadata_errors='ignore').files:
        return bag_dir
    raise ValueError(f'{path} is not a file of the bag {bag_dir} (its {METADATA_FILE} does '
                     f'not list it): repairing it in place would replace that '
                     f'{METADATA_FILE}; repair it with --out DIR')


def _repair_into(found, target_dir, out_dir, backup, compression):
    """Repair the files ``found`` lists into ``target_dir`` (see :func:`repair_bag`)."""
    bag_dir, meta = found.bag_dir, found.metadata
    report = RepairReport(target_dir, notes=[n for n in found.notes if 'interrupted' not in n])
    infos = []
    custom = dict((meta or {}).get('custom_data') or {})
    for full in found.files:
        source = full
        if full in found.leftovers:
            if out_dir is None:
                _restore(full, found.leftovers[full], report)
            else:
                source = found.leftovers[full]
        target = os.path.join(target_dir, os.path.basename(full))
        info = _repair_file(source, target, backup, compression,
                            _counted(meta, full, bag_dir), report)
        for key, value in info.custom_data.items():
            custom.setdefault(key, value)
        infos.append(info)
    for info in infos:
        for name, topic in info.topics.items():
            report.topics[name] = report.topics.get(name, 0) + topic.message_count
    counted = [i for i in infos if i.message_count]
    report.start_time_ns = min((i.start_time_ns for i in counted), default=0)
    report.end_time_ns = max((i.end_time_ns for i in counted), default=0)
    stale = _stale_metadata(found, report, infos, target_dir, bool(counted))
    target = os.path.join(target_dir, METADATA_FILE)
    if stale is None:
        report.metadata_kept = True
        if out_dir is not None:
            with atomic.staged(target) as tmp:
                shutil.copyfile(os.path.join(bag_dir, METADATA_FILE), tmp)
        return report
    report.notes.extend(f'{note}: rewrote {METADATA_FILE}' for note in stale)
    atomic.write_text(target, metadata_yaml(target_dir, infos, custom))
    return report


def _stale_metadata(found, report, infos, target_dir, any_messages):
    """
    Return None to keep ``metadata.yaml`` as it is, else why it is regenerated (notes).

    It is kept only when no file was rewritten or restored, it was read
    without a note (not missing, malformed, or listing a file twice), lists
    the repaired files as they are named, and its counts, starting time and
    duration are the files' (:func:`gyro_emulator.recording.files.metadata_disagreements`).
    The notes are those not said otherwise (a rewritten file and a
    malformed ``metadata.yaml`` are).
    """
    meta = found.metadata
    if report.rewritten or found.leftovers or found.notes:
        return []
    if meta is None:
        return [f'{METADATA_FILE} is missing']
    names = [os.path.relpath(info.path, target_dir) for info in infos]
    if list(meta.get('relative_file_paths') or ()) != names:
        return [f'{METADATA_FILE} lists {meta.get("relative_file_paths")}, the bag has {names}']
    return metadata_disagreements(
        meta, report.message_count, report.topics,
        (report.start_time_ns, report.end_time_ns) if any_messages else None) or None
