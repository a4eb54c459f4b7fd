"""
Model against measurement: find what the simulation gets wrong, name the cause.

``diagnose`` compares a measured record (CSV contract in :mod:`.data`) with
the paper's first-order physics calibrated as a user would (:mod:`.baseline`),
fits every candidate physical cause of :mod:`.effects` and judges them on
held-out data (:mod:`.selection`). :mod:`.truth` makes simulated records with
one hidden effect to prove it; :mod:`.report` writes the Markdown report.
"""

from gyro_emulator.analysis.diagnose.data import load_csv, MeasuredData, write_measured_csv
from gyro_emulator.analysis.diagnose.effects import CATALOGUE, EFFECT_IDS
from gyro_emulator.analysis.diagnose.selection import diagnose, Diagnosis
from gyro_emulator.analysis.diagnose.truth import make_truth, TRUTH_EFFECTS

__all__ = ['CATALOGUE', 'diagnose', 'Diagnosis', 'EFFECT_IDS', 'load_csv',
           'make_truth', 'MeasuredData', 'TRUTH_EFFECTS', 'write_measured_csv']
