#!/usr/bin/env python3
"""
Study: the loop closes on planted causes, one per extended emulator term.

For each planted mechanism (truth generator, ``lab`` profile, seed 5) it
runs ``diagnose``, writes the extended model (``export.extended_model``),
runs ``diagnose --config`` on the same record and prints: the cause found
first, the second run's verdict and causes, the held-out RMSE the first run
claimed for the extension with its 95 % interval, and the RMSE of the
emulator's own output (the second run's baseline). The suite runs four of
these (``test/test_diagnose_export.py``); this prints all of them.

Usage: python bench/loop_planted.py [--rate-hz R] [--seed N]
"""

import argparse
import os
import tempfile
import time

from gyro_emulator.analysis.diagnose import diagnose, export
from gyro_emulator.emulation.truth.generator import make_truth

#: Planted mechanism -> the extended term (or SensorConfig field) it exercises.
PLANTED = {
    'bias_hysteresis': 'extended.bias_hysteresis',
    'bias_warmup': 'extended.bias_time',
    'bias_step': 'extended.bias_step',
    'temperature_rate_bias': 'extended.temperature_rate_bias',
    'pressure_drift': 'extended.pressure_drift',
    'electronics_sf_tempco': 'extended.scale_factor_temperature',
    'scale_factor_step': 'extended.scale_factor_step',
    'bias_temperature': 'bias_temp_coeff_rad_s_k',
}


def closes(planted, rate_hz, seed, folder):
    """Return one row of the table for ``planted``."""
    start = time.perf_counter()
    record, _ = make_truth(planted, seed=seed, sample_rate_hz=rate_hz)
    first = diagnose(record).doc
    part = os.path.join(folder, f'{planted}.yaml')
    export.write_text(part, export.extended_model(first, 'paper')[0])
    second = diagnose(record, config=part).doc
    row = {'planted': planted, 'term': PLANTED[planted],
           'found': [e['effect'] for e in first['selected']],
           'second': second['verdict'], 'further': [e['effect'] for e in second['selected']],
           'own_rmse': second['baseline']['rmse_rad_s'], 'seconds': time.perf_counter() - start}
    if first['selected']:
        row['claimed'] = first['selected'][0]['rmse_rad_s']
        row['interval'] = first['selected'][0]['rmse_interval_rad_s']
    return row


def main():
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate-hz', type=float, default=25.0)
    parser.add_argument('--seed', type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        for planted in PLANTED:
            r = closes(planted, args.rate_hz, args.seed, folder)
            lo, hi = r.get('interval', (float('nan'),) * 2)
            inside = lo <= r['own_rmse'] <= hi
            print(f"{r['planted']:<22} {r['term']:<36} found {','.join(r['found']) or 'none':<26} "
                  f"second {r['second']:<16} further {','.join(r['further']) or 'none':<10} "
                  f"claimed {r.get('claimed', float('nan')):.4g} [{lo:.4g}, {hi:.4g}] "
                  f"own {r['own_rmse']:.4g} {'inside' if inside else 'OUTSIDE'} "
                  f"({r['seconds']:.0f} s)", flush=True)


if __name__ == '__main__':
    main()
