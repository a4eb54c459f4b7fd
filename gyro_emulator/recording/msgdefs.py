"""
Message definitions (ros2msg schemas) and RIHS01 type hashes from the installed .msg files.

The definition of a type is its .msg text with the definitions of every
nested type appended, as rosbag2 writes them (rosbag2
``docs/message_definition_encoding.md``).
"""

import json
import os
import sys

_PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'))


def _share_prefixes():
    """Return the install prefixes to search: AMENT_PREFIX_PATH, then sys.prefix."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.append(sys.prefix)
    return prefixes


def _split_type_name(type_name):
    """Return (package, namespace, name) of ``pkg/msg/Name`` or ``pkg/Name``."""
    parts = type_name.split('/')
    if len(parts) == 2 and all(parts):
        return parts[0], 'msg', parts[1]
    if len(parts) == 3 and all(parts):
        return tuple(parts)
    raise ValueError(
        f'message type {type_name!r} is not understood: expected package/msg/Name')


def _interface_file(type_name, extension):
    package, namespace, name = _split_type_name(type_name)
    for prefix in _share_prefixes():
        path = os.path.join(prefix, 'share', package, namespace, name + extension)
        if os.path.isfile(path):
            return path
    return None


def _msg_dependencies(text, package):
    """
    Return the sorted non-primitive field types named in a .msg text.

    Field types are the first token of each non-comment line (array suffixes
    stripped); names without a package refer to ``package``, as in rosbag2's
    LocalMessageDefinitionSource.
    """
    deps = set()
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        token = line.split()[0]
        if len(line.split()) < 2 or '=' in token:
            continue
        base = token.split('[', 1)[0].split('<=', 1)[0]
        if base in _PRIMITIVES:
            continue
        deps.add(base if '/' in base else f'{package}/{base}')
    return sorted(deps)


_DEFINITION_CACHE = {}


def message_definition(type_name):
    """
    Return the ``ros2msg`` schema text of a message type.

    The text of ``share/<pkg>/msg/<Name>.msg`` comes first; each dependency,
    depth first and in sorted order, follows once after a line of 80 ``=``
    and ``MSG: <pkg>/<Name>`` (rosbag2's LocalMessageDefinitionSource layout,
    which mcap-ros2-support and rosbags parse).

    Parameters
    ----------
    type_name : str
        ``package/msg/Name``.

    Raises
    ------
    ValueError
        If the .msg file of the type or of a dependency is not installed.

    """
    if type_name in _DEFINITION_CACHE:
        return _DEFINITION_CACHE[type_name]
    seen = set()

    def text_of(name):
        path = _interface_file(name, '.msg')
        if path is None:
            raise ValueError(
                f'no .msg definition for {name!r} under share/ of '
                f'{os.pathsep.join(_share_prefixes())}')
        with open(path, encoding='utf-8') as handle:
            return handle.read()

    def append(name, depth):
        if depth > 32:
            raise ValueError(f'message definition of {type_name!r} nests too deeply')
        text = text_of(name)
        out = text
        for dep in _msg_dependencies(text, _split_type_name(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + '=' * 80 + '\nMSG: ' + dep + '\n' + append(dep, depth + 1)
        return out

    result = append(type_name, 0)
    _DEFINITION_CACHE[type_name] = result
    return result


def type_hash(type_name):
    """
    Return the RIHS01 type hash of ``type_name`` ('' if not installed).

    Read from the ``share/<pkg>/msg/<Name>.json`` type description that
    rosidl generates (REP 2011).
    """
    path = _interface_file(type_name, '.json')
    if path is None:
        return ''
    try:
        with open(path, encoding='utf-8') as handle:
            hashes = json.load(handle).get('type_hashes', [])
    except (OSError, ValueError):
        return ''
    package, namespace, name = _split_type_name(type_name)
    full = f'{package}/{namespace}/{name}'
    for entry in hashes:
        if entry.get('type_name') == full:
            return entry.get('hash_string', '')
    return ''
