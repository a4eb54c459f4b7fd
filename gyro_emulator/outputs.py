"""
Where a command writes, checked once before the work starts.

Every command that writes names its inputs and its outputs to
:func:`check` first, so that a run that could not write its results fails
in one line before it reads or computes anything:

* no output is one of the command's inputs, the same file through a link
  included (``os.path.samefile``, real paths), lies inside an input
  directory (a bag), or is a directory that holds an input (replacing it
  would delete the input);
* no two outputs name the same file;
* an output that exists is replaced only with ``overwrite`` (``--overwrite``);
* the folder of every output is a folder, or can be made as one (no part
  of its path is a file), and can be written;
* staging temporaries that a killed run left in those folders
  (``.<name>.<pid>.<hex>.tmp``, :mod:`gyro_emulator.atomic`) are removed
  when their process is proven dead (:func:`gyro_emulator.atomic.remove_stale`).

An :class:`Output` is a file (``kind='file'``), a directory written whole
(``'dir'``: a bag), or files with known names inside a folder
(``'in'``: ``--report DIR``, ``--out-dir DIR``); a plot's format is checked
with its name (:func:`image`).
"""

from dataclasses import dataclass
import os

from gyro_emulator import atomic, plotting


@dataclass(frozen=True)
class Output:
    """
    One output of a command.

    Attributes
    ----------
    option : str
        How the user named it (``'--json'``), for the messages.
    path : str
        The file, the directory, or the folder of ``names``.
    kind : str
        ``'file'``, ``'dir'`` (a directory written whole) or ``'in'`` (the
        files ``names`` inside the folder ``path``).
    names : tuple of str
        With ``kind='in'``: the entries written inside ``path``.

    """

    option: str
    path: str
    kind: str = 'file'
    names: tuple = ()

    def targets(self):
        """Return the paths this output replaces."""
        if self.kind == 'in':
            return tuple(os.path.join(self.path, name) for name in self.names)
        return (self.path,)


#: How a message names what each kind of :class:`Output` needs.
_KIND_NAMES = {'file': 'file', 'dir': 'directory', 'in': 'folder'}


def file(option, path):
    """Return the :class:`Output` of one file; None without a path."""
    return None if path is None else Output(option, os.fspath(path))


def image(option, path):
    """
    Return the :class:`Output` of a plot (None without a path): the file ``savefig`` writes.

    A name without an extension gets PNG's, as matplotlib gives it
    (:func:`gyro_emulator.plotting.image_path`); a format matplotlib does not
    write is refused here, before the work, not after the other outputs.
    """
    if path is None:
        return None
    target, fmt = plotting.image_path(path)
    formats = plotting.image_formats()
    if fmt not in formats:
        raise ValueError(f'{option} {os.fspath(path)}: {fmt!r} is not an image format; allowed: '
                         f'{", ".join(formats)}')
    return Output(option, target)


def directory(option, path):
    """Return the :class:`Output` of a directory written whole (None when ``path`` is None)."""
    return None if path is None else Output(option, os.fspath(path), 'dir')


def inside(option, folder, names):
    """Return the :class:`Output` of the files ``names`` in ``folder`` (None without a folder)."""
    return None if folder is None else Output(option, os.fspath(folder), 'in', tuple(names))


def _real(path):
    return os.path.realpath(os.path.abspath(path))


def _same(a, b):
    """Whether paths ``a`` and ``b`` are the same file (through links too)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return _real(a) == _real(b)


def _within(path, folder):
    """Whether ``path`` lies inside the directory ``folder`` (real paths)."""
    path, folder = _real(path), _real(folder)
    return path != folder and path.startswith(folder.rstrip(os.sep) + os.sep)


def _check_input(output, target, source):
    """Refuse ``target`` (a path of ``output``) when it is, holds, or lies in ``source``."""
    if _same(target, source):
        raise ValueError(f'{output.option} {target} is the input {source}: an output never '
                         'replaces an input; choose another name')
    if os.path.isdir(source) and _within(target, source):
        raise ValueError(f'{output.option} {target} lies inside the input {source}: an output '
                         'never changes an input; choose another folder')
    if output.kind != 'file' and _within(source, target):
        raise ValueError(f'{output.option} {target} holds the input {source}: replacing it '
                         'would delete the input; choose another folder')


def _check_folder(option, path):
    """Refuse an output whose folder is a file, or cannot be made or written."""
    folder = os.path.dirname(os.path.abspath(path))
    probe = folder
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            break
        probe = parent
    if not os.path.isdir(probe):
        raise ValueError(f'{option} {path}: {probe} is a file, not a folder')
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ValueError(f'{option} {path}: cannot write in {probe} (permission denied)')


def _check_existing(output, target, overwrite):
    if not os.path.lexists(target):
        return
    if output.kind == 'file' and os.path.isdir(target) and not os.path.islink(target):
        raise ValueError(f'{output.option} {target} is a directory: give a file name')
    if output.kind == 'dir' and not os.path.isdir(target):
        raise ValueError(f'{output.option} {target} is a file: give a directory name')
    if not overwrite:
        raise ValueError(f'{output.option} {target} exists: pass --overwrite to replace it')


def check(outputs, inputs=(), overwrite=False):
    """
    Check every output of a command before the work starts (module docstring).

    Parameters
    ----------
    outputs : iterable of Output or None
        What the command writes (None entries, for options not given, are skipped).
    inputs : iterable of str or None
        Every file or directory the command reads (None entries skipped;
        preset names that are not paths are ignored).
    overwrite : bool
        Whether existing outputs may be replaced.

    Raises
    ------
    ValueError
        One line naming the option, the path and what is wrong.

    """
    outputs = [o for o in outputs if o is not None]
    sources = [os.fspath(s) for s in inputs if s is not None and os.path.lexists(os.fspath(s))]
    seen = {}
    for output in outputs:
        if not output.path:             # '' would be the working directory
            raise ValueError(f'{output.option} {output.path!r}: an empty name; give a '
                             f'{_KIND_NAMES[output.kind]} name')
        if output.kind == 'in':
            _check_folder(output.option, os.path.join(output.path, 'x'))
            if os.path.lexists(output.path) and not os.path.isdir(output.path):
                raise ValueError(f'{output.option} {output.path} is a file, not a folder')
        for target in output.targets():
            if not os.path.basename(os.path.abspath(target)) or (
                    output.kind == 'file' and target.endswith(('/', os.sep))):
                raise ValueError(f'{output.option} {target!r}: no file name')
            for source in sources:
                _check_input(output, target, source)
            for other, option in seen.items():
                if _same(target, other):
                    raise ValueError(f'{option} and {output.option} both write {target}: '
                                     'give them different names')
            seen[target] = output.option
            _check_folder(output.option, target)
            _check_existing(output, target, overwrite)
    for folder in {os.path.dirname(os.path.abspath(t)) for t in seen}:
        atomic.remove_stale(folder)
