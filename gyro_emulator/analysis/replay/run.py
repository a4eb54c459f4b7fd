"""
One offline replay run: a bag in; the emulated bag, the report and the plots out.

:func:`replay_bag` is what ``gyro-emulator replay`` does once its arguments
are parsed: open the bag (:func:`gyro_emulator.recording.record.open_bag`,
tolerant of damage), take the sensor configuration and seed as given or else
from the bag's ``custom_data``, read the inputs (:func:`load_inputs`),
emulate, compare, and write ``DIR/emulated``, the report and the plots.
"""

from dataclasses import dataclass
import os

from gyro_emulator.analysis.replay.inputs import emulate, load_inputs
from gyro_emulator.analysis.replay.report import compare, report_text, write_report
from gyro_emulator.emulation.emulator_bag import noise_sigmas, write_output_bag
from gyro_emulator.emulation.simulate import staged_output
from gyro_emulator.recording import record
from gyro_emulator.recording.files import inside_bag
from gyro_emulator.sensor.config import load_sensor_config, PRESET_NAMES
from gyro_emulator.sensor.streams import seed_from_name
from gyro_emulator.validation import check_ambient_c, check_rate_hz

#: Sensor configuration when neither the caller nor the bag names one.
DEFAULT_CONFIG = 'paper'
#: The node's ``seed`` that means "from the node's fully qualified name".
SEED_FROM_NAME = -1
#: What ``DIR`` holds after a replay (``emulated`` is the bag).
OUTPUTS = ('emulated', 'report.md', 'report.json', 'rates.png', 'residual.png', 'allan.png')


@dataclass(frozen=True)
class ReplayRun:
    """
    What a replay run wrote.

    ``bag_dir`` is the emulated bag directory, ``samples`` the number of
    emulated samples, ``report`` the report text (as in ``report.md``) and
    ``paths`` the report and plot files written.
    """

    bag_dir: str
    samples: int
    report: str
    paths: list


def bag_config(reader):
    """
    Return the sensor configuration a bag's ``custom_data`` names, refusing files outside it.

    A bag is untrusted input: its ``sensor_config`` may be a preset name or
    a YAML file inside the bag directory (as ``relative_file_paths``); a
    path leaving the directory raises a one-line ValueError that shows the
    path, never the file.
    """
    name = reader.custom_data.get('sensor_config', DEFAULT_CONFIG)
    if name in PRESET_NAMES:
        return name
    try:
        return inside_bag(reader.path, name, "the bag's custom_data sensor_config is")
    except ValueError as exc:
        raise ValueError(f'{exc} (choose the sensor with --config)') from None


def _bag_seed(reader):
    """
    Return the seed a bag's ``custom_data`` gives (0 without one).

    A node recording stores its ``seed`` parameter: -1 means the node drew its
    seed from its fully qualified name (``streams.seed_from_name``), which is
    taken from ``custom_data`` ``node`` when the bag holds it; without it the
    seed cannot be known and the error says how to give it.
    """
    value = reader.custom_data.get('seed', '0')
    try:
        seed = int(value)
    except ValueError:
        raise ValueError(f"the bag's custom_data seed {value[:40]!r} is not an integer "
                         '(choose one with --seed)') from None
    if seed == SEED_FROM_NAME and reader.custom_data.get('node'):
        return seed_from_name(reader.custom_data['node'])
    if seed < 0:
        raise ValueError(f"the bag's custom_data seed = {seed}: the node drew its seed from "
                         'its name, which this bag does not record; give --seed N with the '
                         "seed the node logged at start ('seed N (from the node name)'), or "
                         'any N >= 0 for fresh noise')
    return seed


def _ignore(note):
    """Drop a warning."""


def check_options(seed, rate_hz, temp_c):
    """
    Refuse a seed, model rate or ambient the replay cannot use, before the bag is read.

    One line each, ``field = value is out of range: allowed ...``: the
    command line names the option as typed (``--temp-c nan is out of
    range``), not the model field that would have refused it after the work.
    """
    if seed is not None and seed < 0:
        raise ValueError(f'seed = {seed} is out of range: allowed >= 0')
    check_rate_hz(rate_hz)
    check_ambient_c(temp_c)


def replay_bag(bag_path, out_dir, config=None, seed=None, plots=True, overwrite=False,
               warn=_ignore, **input_options):
    """
    Replay a bag through the model and write the emulated bag and the report.

    Parameters
    ----------
    bag_path : str
        Bag directory or ``.mcap`` file.
    out_dir : str
        Output directory: ``emulated`` (a bag), ``report.md``, ``report.json``
        and the plots.
    config : str, optional
        Sensor preset or YAML (default: the bag's ``custom_data``
        ``sensor_config``, else ``paper``).
    seed : int, optional
        Random seed (default: the bag's ``custom_data`` ``seed``, else 0).
    plots : bool
        Write the PNG plots.
    overwrite : bool
        Replace a non-empty ``out_dir/emulated``; without it that is an error.
    warn : callable
        ``warn(note)`` for each thing a damaged bag lost.
    **input_options
        Keywords of :func:`load_inputs` (source, topics, rate_hz, temp_c,
        use_log_time).

    Returns
    -------
    ReplayRun

    Raises
    ------
    FileExistsError
        ``out_dir/emulated`` exists, is not empty and ``overwrite`` is false.

    """
    if not record.is_bag(bag_path):
        raise ValueError(f'{bag_path} is not a bag (a directory or an .mcap file)')
    check_options(seed, input_options.get('rate_hz'), input_options.get('temp_c'))
    reader = record.open_bag(bag_path)
    for note in reader.problems:
        warn(f'incomplete bag, {note}')
    bag_dir = os.path.join(out_dir, 'emulated')
    if os.path.isdir(bag_dir) and os.listdir(bag_dir) and not overwrite:
        raise FileExistsError(f'{bag_dir} exists and is not empty (pass --overwrite)')
    config_name = config or bag_config(reader)
    seed = seed if seed is not None else _bag_seed(reader)
    sensor_config = load_sensor_config(config_name)
    shown = len(reader.problems)
    inputs = load_inputs(reader, **input_options)
    for note in reader.problems[shown:]:
        warn(note)
    _, batch = emulate(inputs, sensor_config, seed)
    comparison = compare(inputs, batch)
    header = [f'bag: {os.path.abspath(bag_path)}', f'sensor config: {config_name}',
              f'seed: {seed}'] + [f'recovered: {note}' for note in reader.problems]
    sigma, accel_sigma = noise_sigmas(sensor_config, inputs.rate_hz)
    with staged_output(bag_dir, overwrite) as partial:     # complete or absent
        write_output_bag(partial, inputs, batch, comparison, sigma, custom_data={
            'generator': 'gyro-emulator replay', 'source_bag': os.path.abspath(bag_path),
            'sensor_config': str(config_name), 'seed': str(seed),
            'rate_hz': repr(inputs.rate_hz), 'source': inputs.source},
            accel_sigma_m_s2=accel_sigma, name=os.path.abspath(bag_dir))
    paths = write_report(out_dir, comparison, inputs, header, plots=plots)
    return ReplayRun(bag_dir=bag_dir, samples=len(inputs.stamp_ns),
                     report=report_text(comparison, inputs, header), paths=paths)
