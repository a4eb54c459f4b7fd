"""
The ``diagnose`` command's run: one request in, the record diagnosed, what it asks written.

:class:`Request` is what ``gyro-emulator diagnose`` asks for, checked once
when it is made. :func:`execute` loads the record, diagnoses it (numerical
warnings kept off the terminal: :func:`quiet_numerics`), and writes what the
request names in this order: the verdict on the terminal, the JSON, the
report, the extended sensor YAML (:mod:`.export`, with ``--noise`` the
record's noise terms from :mod:`.record_noise`). It speaks through the
caller's console: ``out(line)`` and ``err(line)`` for the terminal and
``write_json(path, doc)`` for the command line's JSON writer.
"""

import contextlib
from dataclasses import dataclass
import math
import os
import warnings

from gyro_emulator import outputs
from gyro_emulator.recording import topics
from gyro_emulator.sensor.config import config_source
from gyro_emulator.validation import check_range


@dataclass(frozen=True)
class Request:
    """
    What ``gyro-emulator diagnose`` asks for (the options of :mod:`gyro_emulator.cli.diagnose`).

    The record (``source``: a CSV or a bag, its topics, ``axis``, ``static``), the baseline
    (``preset``, ``config``, ``ref_temp_c``), the selection (``folds``,
    ``effects``, ``alpha``, ``outlier_sigma``, ``max_causes``, ``reference``:
    a static record of the same part whose noise is held fixed) and the
    outputs (``json``, ``report``, ``write_config`` with ``noise`` and
    ``overwrite``). Out-of-range values raise a one-line ValueError.
    """

    source: str
    rate_topic: str = topics.RATE_CMD.name
    temp_topic: str = topics.TEMPERATURE_CMD.name
    gyro_topic: str = topics.IMU_OUT.name
    accel_topic: str = None
    axis: str = None
    static: bool = False
    preset: str = 'paper'
    config: str = None
    ref_temp_c: float = None
    folds: int = 8
    effects: tuple = None
    alpha: float = 0.01
    outlier_sigma: float = 6.0
    max_causes: int = 4
    json: str = None
    report: str = None
    write_config: str = None
    noise: bool = False
    overwrite: bool = False
    reference: str = None

    def __post_init__(self):
        """Check the selection options and that ``noise`` has a file to go to."""
        check_range('diagnose', 'alpha', self.alpha, 0.0, 1.0, '', high_open=True)
        if not math.isinf(self.outlier_sigma):
            check_range('diagnose', 'outlier_sigma', self.outlier_sigma, 3.0, 1e6, 'sigma',
                        low_open=False)
        check_range('diagnose', 'max_causes', self.max_causes, 1, 20, '', low_open=False)
        if self.config is not None and self.preset != 'paper':
            raise ValueError(f'diagnose: --preset {self.preset} sets the device of the paper '
                             "baseline; with --config the baseline is that configuration's "
                             'output, with its own device: drop --preset, or give the '
                             'configuration that device')
        if self.noise and not self.write_config:
            raise ValueError('diagnose: --noise writes noise terms into the --write-config '
                             'file: give --write-config OUT.yaml too')

    @property
    def sense_axis(self):
        """Return the diagnosed axis: ``axis``, else z (a bag's default)."""
        return self.axis or 'z'


def execute(request, console):
    """
    Run a :class:`Request`: load, diagnose, report, write (see the module docstring).

    Every output is checked before the record is read
    (:func:`gyro_emulator.outputs.check`: not an input, not existing without
    ``overwrite``, its folder writable). Returns the diagnosis.
    """
    # The analysis (scipy, numba: 0.9 s, 2.4 s cold) is imported here, not at
    # the top: `gyro-emulator --help` imports the command line's modules.
    from gyro_emulator.analysis.diagnose import data, diagnose, report, to_json

    outputs.check([outputs.file('--json', request.json),
                   outputs.inside('--report', request.report, ('report.md',) + tuple(
                       f'residuals_{key}.png' for key, _, _ in report.PLOTS)),
                   outputs.file('--write-config', request.write_config)],
                  inputs=[request.source, request.reference, config_source(request.config)],
                  overwrite=request.overwrite)
    if request.reference is not None and not os.path.exists(request.reference):
        raise ValueError(f'diagnose: --reference {request.reference}: no such file or '
                         'directory: allowed: a static record of the same part (CSV or bag)')
    record = data.load_measured(request.source, rate_topic=request.rate_topic,
                                temp_topic=request.temp_topic, gyro_topic=request.gyro_topic,
                                accel_topic=request.accel_topic, axis=request.axis,
                                static=request.static)
    for note in record.recovery:
        console.err(f'gyro-emulator diagnose: warning: {note}')
    reference = None if request.reference is None else data.load_measured(
        request.reference, gyro_topic=request.gyro_topic, axis=request.axis, static=True)
    with quiet_numerics():
        diagnosis = diagnose(record, preset=request.preset, ref_temp_c=request.ref_temp_c,
                             folds=request.folds, effects=request.effects, alpha=request.alpha,
                             outlier_threshold=request.outlier_sigma,
                             max_causes=request.max_causes, config=request.config,
                             axis=request.sense_axis, reference=reference)
        for line in report.terminal_lines(diagnosis):
            console.out(line)
        if request.json:
            console.write_json(request.json, to_json(diagnosis))
        if request.report:
            console.out(f'wrote {report.write_report(diagnosis, request.report)}')
    if request.write_config:
        _write_config(request, diagnosis, record, console)
    return diagnosis


def _write_config(request, diagnosis, record, console):
    """Write the extended model (:mod:`.export`), with ``--noise`` the record's noise terms."""
    from gyro_emulator.analysis.diagnose import export, record_noise

    # the per-axis amplitudes go to the diagnosed axis: --axis, else z (a bag's default)
    if request.config is None:
        model = export.extended_model(
            diagnosis, 'paper', axis=request.sense_axis, device=request.preset,
            config_name=f"sensor preset 'paper', device {request.preset!r}")
    else:
        model = export.extended_model(diagnosis, request.config, axis=request.sense_axis,
                                      config_name=request.config)
    model = model.with_measured_range(record)
    if request.noise:
        with quiet_numerics():
            model = model.with_noise(record_noise.identify(
                model.config, record, request.sense_axis, request.outlier_sigma))
            model = model.with_accel_noise(record_noise.identify_accel(
                record, request.outlier_sigma, request.gyro_topic))
    text = model.text()
    export.write_text(request.write_config, text, request.overwrite)
    for cause, why in model.warnings:
        console.err(f'gyro-emulator diagnose: warning: {cause} written commented out: {why}')
    console.out(f'wrote {request.write_config}')


@contextlib.contextmanager
def quiet_numerics():
    """
    Keep numpy's and scipy's numerical warnings off the user's terminal.

    An empty slice or a degenerate fit on an odd record is handled where it
    happens (a NaN the verdict reads as "not measurable"); the warning that
    came with it says nothing the report does not. A failure that is not a
    ValueError or OSError (which :func:`gyro_emulator.cli.main` prints as one
    line) is turned into one, naming what failed.
    """
    import numpy as np

    with warnings.catch_warnings(), np.errstate(all='ignore'):
        warnings.simplefilter('ignore', RuntimeWarning)
        warnings.simplefilter('ignore', UserWarning)
        try:
            yield
        except (ValueError, OSError, KeyboardInterrupt):
            raise
        except Exception as exc:
            raise ValueError(f'the diagnosis failed ({type(exc).__name__}: {exc}); please '
                             'report it with the input') from exc
