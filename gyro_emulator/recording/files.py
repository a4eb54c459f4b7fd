"""
The files of a bag: ``metadata.yaml`` read as untrusted input, and the MCAP files it names.

A bag is untrusted input. :func:`load_metadata` reads ``metadata.yaml``
with a bounded YAML load (size cap, no aliases) and checks the types of the
fields this package uses against the rosbag2 schema; :func:`inside_bag`
refuses a path the bag names that leaves the bag directory;
:func:`resolve_bag` lists the MCAP files once each, and finds the files an
interrupted ``bag repair`` left (``<file>.repair-tmp``, ``<file>.orig``).
"""

from dataclasses import dataclass, field
import os

from gyro_emulator.recording.mcap_writer import MCAP_MAGIC
from gyro_emulator.recording.metadata import METADATA_FILE
from gyro_emulator.resources import load_yaml_text, read_bytes_bounded

#: Largest ``metadata.yaml`` read, bytes (rosbag2 writes a few kB per topic).
MAX_METADATA_BYTES = 8 << 20
#: Suffixes of the files ``bag repair`` writes beside an MCAP file.
REPAIR_TMP = '.repair-tmp'
BACKUP = '.orig'
_SCALARS = (str, int, float, bool)
#: How to make a bag this package reads from one it refuses (rosbags is a dependency).
CONVERT = 'convert it with: rosbags-convert --src BAG --dst NEW_BAG --dst-storage mcap'


def _yaml_document(text, path):
    """Return the YAML document of ``text``; ValueError for aliases or malformed YAML."""
    # the package's one bounded loader; rosbag2 metadata has no aliases: none is taken
    return load_yaml_text(text, f'{path} (rosbag2 metadata)', aliases=False)


def _type_error(path, name, value, expected):
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:57] + '...'
    return ValueError(f'{path}: {name} is {shown} ({type(value).__name__}): expected '
                      f'{expected}; gyro-emulator bag repair regenerates metadata.yaml')


def _check_fields(meta, path):
    """Check the types of the rosbag2 fields this package reads; return ``meta``."""
    key = 'rosbag2_bagfile_information'
    for name, kinds, expected in (
            ('version', (int,), 'an integer'),
            ('message_count', (int,), 'an integer'),
            ('storage_identifier', (str,), 'a string'),
            ('relative_file_paths', (list,), 'a list of file names'),
            ('files', (list,), 'a list of mappings'),
            ('topics_with_message_count', (list,), 'a list of mappings'),
            ('custom_data', (dict,), 'a mapping of names to strings')):
        value = meta.get(name)
        if value is not None and (not isinstance(value, kinds) or isinstance(value, bool)):
            raise _type_error(path, f'{key}.{name}', value, expected)
    for i, rel in enumerate(meta.get('relative_file_paths') or ()):
        if not isinstance(rel, str) or not rel:
            raise _type_error(path, f'{key}.relative_file_paths[{i}]', rel, 'a file name')
    for name in ('files', 'topics_with_message_count'):
        for i, item in enumerate(meta.get(name) or ()):
            if not isinstance(item, dict):
                raise _type_error(path, f'{key}.{name}[{i}]', item, 'a mapping')
    for name, value in (meta.get('custom_data') or {}).items():
        if not isinstance(name, str) or not isinstance(value, _SCALARS):
            raise _type_error(path, f'{key}.custom_data[{name!r}]', value, 'a string')
    return meta


def check_storage(meta, path):
    """
    Refuse a bag this package cannot read as it is, in one line naming the field.

    rosbag2 bags in sqlite3 storage (``storage_identifier``), or compressed
    as whole files or message by message (``compression_mode`` ``file`` or
    ``message``), are not MCAP files of CDR messages: reading them as such
    would hand out compressed bytes as messages, and ``bag repair``
    regenerating their ``metadata.yaml`` would drop what says so. Uncompressed
    rosbag2 MCAP bags (``compression_mode`` empty or ``none``) pass; zstd or
    lz4 chunks inside the MCAP file are read (the MCAP compression).
    """
    key = 'rosbag2_bagfile_information'
    storage = meta.get('storage_identifier')
    if storage not in (None, '', 'mcap'):
        raise ValueError(f'{path}: {key}.storage_identifier is {storage!r}: expected "mcap" '
                         f'(rosbag2 MCAP bags only); {CONVERT}')
    mode = meta.get('compression_mode')
    if mode is not None and str(mode).lower() not in ('', 'none'):
        raise ValueError(f'{path}: {key}.compression_mode is {mode!r} (format '
                         f'{meta.get("compression_format")!r}): expected "" or "none" '
                         '(uncompressed rosbag2 files; MCAP chunk compression is read); '
                         f'{CONVERT}')
    return meta


def load_metadata(path):
    """
    Return the ``rosbag2_bagfile_information`` mapping of a ``metadata.yaml``.

    Bounded: a file over :data:`MAX_METADATA_BYTES` or with a YAML alias is
    refused before it is built (a billion-laughs alias bomb costs nothing).
    The types of ``version``, ``message_count``, ``relative_file_paths``,
    ``files``, ``topics_with_message_count`` and ``custom_data`` are checked
    (rosbag2 metadata version 9); ``custom_data`` values become strings.

    Raises
    ------
    ValueError
        One line naming the file, the field, its value and what was expected.

    """
    raw = read_bytes_bounded(path, MAX_METADATA_BYTES, 'rosbag2 metadata file')
    text = raw.decode('utf-8', 'replace')
    loaded = _yaml_document(text, path)
    meta = loaded.get('rosbag2_bagfile_information') if isinstance(loaded, dict) else None
    if not isinstance(meta, dict):
        shown = loaded if not isinstance(loaded, dict) else meta
        raise _type_error(path, 'rosbag2_bagfile_information', shown, 'a mapping')
    meta = _check_fields(dict(meta), path)
    if meta.get('custom_data'):
        meta['custom_data'] = {k: str(v) for k, v in meta['custom_data'].items()}
    return meta


def _span_disagreements(meta, span_ns):
    """Return notes where ``metadata.yaml``'s starting time or duration is not the files' span."""
    start, end = span_ns
    notes = []
    for name, key, value in (('starting_time', 'nanoseconds_since_epoch', start),
                             ('duration', 'nanoseconds', end - start)):
        given = meta.get(name)
        given = given.get(key) if isinstance(given, dict) else None
        if isinstance(given, int) and not isinstance(given, bool) and given != value:
            notes.append(f'metadata.yaml gives {name} {given} ns, the files {value} ns')
    return notes


def metadata_disagreements(meta, message_count, topic_counts, span_ns=None):
    """
    Return where ``metadata.yaml`` disagrees with the files, one note each.

    ``rosbags`` and ``ros2 bag info`` report ``metadata.yaml``'s counts, this
    package the files' (their summaries, or a scan): a difference means a
    reader of the bag is told something else than what it holds.
    ``topic_counts`` maps each topic in the files to its count; ``span_ns``
    (first and last log time of the files' messages, ns) also checks the
    ``starting_time`` and ``duration`` it gives. ``bag info`` says these
    notes, and ``bag repair`` rewrites a ``metadata.yaml`` only when there is one.
    """
    if not meta:
        return []
    notes = [] if span_ns is None else _span_disagreements(meta, span_ns)
    count = meta.get('message_count')
    if isinstance(count, int) and count != message_count:
        notes.append(f'metadata.yaml counts {count} messages, the files hold {message_count} '
                     "(rosbags and ros2 bag info report metadata.yaml's count)")
    listed = {}             # a topic listed once per connection (rosbags): their sum
    for entry in meta.get('topics_with_message_count') or ():
        topic = (entry.get('topic_metadata') or {}) if isinstance(entry, dict) else {}
        name, count = topic.get('name') if isinstance(topic, dict) else None, \
            entry.get('message_count') if isinstance(entry, dict) else None
        if isinstance(name, str) and isinstance(count, int):
            listed[name] = listed.get(name, 0) + count
    for name, count in listed.items():
        if count != topic_counts.get(name, 0):
            notes.append(f'metadata.yaml counts {count} messages on {name}, the files hold '
                         f'{topic_counts.get(name, 0)}')
    return notes


def inside_bag(bag_dir, name, what):
    """
    Return the real path of ``name``, a path the bag gives, refusing one outside ``bag_dir``.

    ``what`` says where the bag gives it (for the error, e.g. ``'metadata.yaml
    lists'``). Absolute paths, ``..`` and symbolic links that leave the
    directory raise a one-line ValueError that shows the path only.
    """
    root = os.path.realpath(bag_dir)
    full = os.path.realpath(os.path.join(root, str(name)))
    if os.path.isabs(str(name)) or os.path.commonpath([full, root]) != root:
        raise ValueError(f'{what} {str(name)!r}, which is outside the bag directory '
                         f'{bag_dir}: allowed file names inside it only')
    return full


@dataclass
class BagFiles:
    """
    The files of one bag.

    Attributes
    ----------
    bag_dir : str
        The bag directory.
    files : list of str
        Its MCAP files, each once, in order.
    metadata : dict or None
        ``rosbag2_bagfile_information`` (None without ``metadata.yaml``).
    notes : list of str
        What was noticed on the way (a file listed twice, a file an
        interrupted repair left in place of the original).
    leftovers : dict of str to str
        MCAP file (missing) -> the file of an interrupted repair read in its place.

    """

    bag_dir: str
    files: list
    metadata: dict = None
    notes: list = field(default_factory=list)
    leftovers: dict = field(default_factory=dict)


def _ends_with_magic(path):
    """Return whether ``path`` ends with the MCAP magic (a finished file)."""
    try:
        with open(path, 'rb') as handle:
            handle.seek(max(0, os.fstat(handle.fileno()).st_size - len(MCAP_MAGIC)))
            return handle.read() == MCAP_MAGIC
    except OSError:
        return False


def stand_in(mcap_path):
    """
    Return the file an interrupted repair left for the missing ``mcap_path``, or None.

    The repaired temporary file when it was finished (it ends with the MCAP
    magic), else the original kept as ``.orig``, else an unfinished temporary file.
    """
    candidates = [mcap_path + REPAIR_TMP, mcap_path + BACKUP, mcap_path + REPAIR_TMP]
    for i, candidate in enumerate(candidates):
        if os.path.isfile(candidate) and (i > 0 or _ends_with_magic(candidate)):
            return candidate
    return None


def _listed(bag_dir, meta, meta_path, result):
    """Add the files ``metadata.yaml`` lists (each once, inside the bag) to ``result``."""
    for rel in meta['relative_file_paths']:
        full = inside_bag(bag_dir, rel, f'{meta_path} lists')
        if full in result.files or full in result.leftovers:
            result.notes.append(f'{METADATA_FILE} lists {rel} more than once: read once')
            continue
        if not os.path.isfile(full):
            found = stand_in(full)
            if found is None:
                raise FileNotFoundError(f'{meta_path} lists {rel}, which is missing')
            result.leftovers[full] = found
        result.files.append(full)


def resolve_bag(path, metadata_errors='raise'):
    """
    Return the :class:`BagFiles` of a bag directory, ``metadata.yaml`` or ``.mcap`` file.

    Parameters
    ----------
    path : str
        The bag.
    metadata_errors : str
        ``'raise'``: a malformed ``metadata.yaml`` raises ValueError;
        ``'ignore'``: it is noted and the directory's ``.mcap`` files are
        used (what ``bag repair`` does before it rewrites the file).

    """
    path = os.path.abspath(path)
    if os.path.isfile(path):
        if not path.endswith(METADATA_FILE):
            return BagFiles(os.path.dirname(path), [path])
        path = os.path.dirname(path)
    if not os.path.isdir(path):
        raise FileNotFoundError(f'no bag at {path} (expected a bag directory or .mcap file)')
    result = BagFiles(path, [])
    meta_path = os.path.join(path, METADATA_FILE)
    if os.path.isfile(meta_path):
        try:
            result.metadata = load_metadata(meta_path)
        except ValueError as exc:
            if metadata_errors == 'raise':
                raise
            result.notes.append(f'{exc}: ignored, the files were listed from the directory')
    if result.metadata is not None:
        check_storage(result.metadata, meta_path)     # never ignored: repair would drop it
    if result.metadata is not None and result.metadata.get('relative_file_paths'):
        _listed(path, result.metadata, meta_path, result)
    else:
        names = sorted(os.listdir(path))
        result.files = [os.path.join(path, n) for n in names if n.endswith('.mcap')]
        for name in names:
            for suffix in (BACKUP, REPAIR_TMP):
                full = os.path.join(path, name[:-len(suffix)])
                if (name.endswith('.mcap' + suffix) and full not in result.files
                        and full not in result.leftovers):
                    result.leftovers[full] = stand_in(full)
                    result.files.append(full)
        result.files.sort()
    if not result.files:
        logs = sorted(n for n in os.listdir(path) if n.endswith(('.csv', '.csv.gz')))
        other = sorted(n for n in os.listdir(path) if '.db3' in n or n.endswith('.mcap.zstd'))
        if other:
            raise FileNotFoundError(
                f'no .mcap file in bag directory {path}: it holds {other[0]}, a rosbag2 '
                f'sqlite3 or file-compressed bag (rosbag2 MCAP bags only); {CONVERT}')
        raise FileNotFoundError(f'no .mcap file in bag directory {path}' + (
            f': it holds {", ".join(logs[:3])}{" ..." if len(logs) > 3 else ""}; give the '
            'file itself' if logs else ''))
    for full, found in result.leftovers.items():
        result.notes.append(f'{os.path.basename(full)} is missing: read '
                            f'{os.path.basename(found)}, left by an interrupted repair '
                            f'(gyro-emulator bag repair {path} restores it)')
    return result
