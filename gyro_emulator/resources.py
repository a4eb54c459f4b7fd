"""
Files that ship with the package: the ``config/`` directory and YAML reading.

There is one way to find ``config/`` (:func:`config_dir`) and one YAML reader
(:func:`read_yaml`, bounded: :func:`load_yaml_text`); presets, profiles,
scenarios, faults, fleets, node parameters and bag metadata use it.
"""

import os
import sys

#: A file every ``config/`` directory of this package holds.
_MARKER = 'sensor_paper.yaml'


def config_dir():
    """
    Return the directory holding the presets, profiles and node defaults.

    In order: ``config/`` of the source tree when running from a checkout;
    ``<prefix>/share/gyro_emulator/config`` of the first ``AMENT_PREFIX_PATH``
    prefix that has it (a colcon install, as ``ros2 run`` finds it); the
    pip-installed ``<sys.prefix>/share/gyro_emulator/config``.
    """
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    candidates = [os.path.join(here, 'config')]
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            candidates.append(os.path.join(prefix, 'share', 'gyro_emulator', 'config'))
    candidates.append(os.path.join(sys.prefix, 'share', 'gyro_emulator', 'config'))
    for candidate in candidates:
        if os.path.isfile(os.path.join(candidate, _MARKER)):
            return candidate
    return candidates[-1]


def config_file(name):
    """Return the path of ``name`` inside :func:`config_dir`."""
    return os.path.join(config_dir(), name)


#: Largest YAML file read, bytes (a sensor, fleet or parameters file is a few kB;
#: a bag's metadata a few kB per topic).
MAX_YAML_BYTES = 8 << 20
#: Deepest nesting of mappings and sequences accepted (the files nest 5 deep).
MAX_YAML_DEPTH = 64
#: Most nodes a document may hold once its aliases are expanded (a billion-laughs
#: document of a few hundred bytes expands to 10^9).
MAX_YAML_NODES = 1_000_000


def _yaml():
    """Return PyYAML and its safe loader (the C one when PyYAML has libyaml)."""
    # `gyro-emulator --help` imports this module; yaml (20 ms) waits for a file.
    import yaml

    return yaml, getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def _shape(yaml, loader, text, where):
    """
    Scan the events: refuse deep nesting and repeated keys; return whether there are aliases.

    A key given twice in one mapping is refused (line and key named): the
    YAML loader would keep the last value and drop the first without a word.
    Keys are compared as written (scalar keys; ``<<`` merges are left to the
    loader).
    """
    aliases, frames = False, []        # per open collection: [keys, next is a key] or None
    for event in yaml.parse(text, Loader=loader):
        if isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            frames.pop()
            continue
        if isinstance(event, (yaml.ScalarEvent, yaml.AliasEvent, yaml.MappingStartEvent,
                              yaml.SequenceStartEvent)) and frames and frames[-1] is not None:
            frame = frames[-1]
            if frame[1] and isinstance(event, yaml.ScalarEvent) and event.value != '<<':
                if event.value in frame[0]:
                    raise ValueError(f'{where}: line {event.start_mark.line + 1}: key '
                                     f'{event.value!r} is given twice in one mapping (YAML '
                                     'would keep the last silently): refused')
                frame[0].add(event.value)
            frame[1] = not frame[1]
        if isinstance(event, yaml.AliasEvent):
            aliases = True
        elif isinstance(event, yaml.MappingStartEvent):
            frames.append([set(), True])
        elif isinstance(event, yaml.SequenceStartEvent):
            frames.append(None)
        if len(frames) > MAX_YAML_DEPTH:
            raise ValueError(f'{where}: YAML nested more than {MAX_YAML_DEPTH} levels deep '
                             'refused')
    return aliases


def _expanded_nodes(yaml, root, where):
    """Return the node count of ``root`` with every alias expanded; refuse a cycle or too many."""
    sizes, on_path, stack = {}, set(), [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = ([] if isinstance(node, yaml.ScalarNode) else
                    [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode)
                    else list(node.value))
        if done:
            on_path.discard(key)
            sizes[key] = 1 + sum(sizes[id(c)] for c in children)
            if sizes[key] > MAX_YAML_NODES:
                raise ValueError(f'{where}: YAML aliases expand to more than {MAX_YAML_NODES} '
                                 'nodes: refused')
            continue
        if key in sizes:
            continue
        if key in on_path:
            raise ValueError(f'{where}: a YAML alias refers to itself (a recursive anchor): '
                             'refused')
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in sizes)
    return sizes[id(root)]


def load_yaml_text(text, where, aliases=True):
    """
    Return the document of the YAML ``text`` (safe loader), bounded.

    The one YAML loader of the package: sensor, fleet, profile, scenario and
    fault files, node parameter files and bag metadata go through it. Refused
    in one line naming ``where``: nesting deeper than :data:`MAX_YAML_DEPTH`;
    with ``aliases`` false any alias, else aliases that expand to more than
    :data:`MAX_YAML_NODES` nodes or refer to themselves; malformed YAML (the
    parser's account of where, shortened).
    """
    from gyro_emulator.validation import shorten

    yaml, loader_class = _yaml()
    try:
        if not _shape(yaml, loader_class, text, where):
            return yaml.load(text, Loader=loader_class)
        if not aliases:
            raise ValueError(f'{where}: YAML aliases are refused here (they can expand without '
                             'bound)')
        loader = loader_class(text)
        try:
            root = loader.get_single_node()
            if root is None:
                return None
            _expanded_nodes(yaml, root, where)
            return loader.construct_document(root)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        account = shorten(' '.join(str(exc).split()), 300)
        raise ValueError(f'{where}: malformed YAML: {account}') from None


def read_bytes_bounded(path, max_bytes, what='file'):
    """Return the bytes of the file at ``path``; ValueError if unreadable or over ``max_bytes``."""
    try:
        with open(path, 'rb') as handle:
            raw = handle.read(max_bytes + 1)
    except OSError as exc:
        raise ValueError(f'{path}: cannot read: {exc}') from None
    if len(raw) > max_bytes:
        raise ValueError(f'{path} is over {max_bytes >> 20} MiB: too large for a {what}')
    return raw


def read_yaml(path, max_bytes=MAX_YAML_BYTES):
    """
    Return the document of the YAML file at ``path`` (:func:`load_yaml_text`: bounded).

    An unreadable file, one over ``max_bytes``, text that is not UTF-8 or
    malformed YAML raises ValueError naming the path and, for malformed
    YAML, the parser's account of where it failed.
    """
    raw = read_bytes_bounded(path, max_bytes, 'YAML file')
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ValueError(f'{path}: cannot read: not UTF-8 text ({exc.reason} at byte '
                         f'{exc.start})') from None
    return load_yaml_text(text, path)
