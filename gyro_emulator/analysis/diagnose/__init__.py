"""
Model against measurement: find what the simulation gets wrong, name the cause.

``diagnose`` compares a measured record (the contract in :mod:`.data`) with
the paper's first-order physics calibrated as a user would (:mod:`.baseline`).
It sets outliers aside (:mod:`.screening`), adds physical and generic
causes (:mod:`.effects`, :mod:`.generic`, :mod:`.models`) by forward
selection on held-out evidence (:mod:`.cv`, :mod:`.selection`) judged
against the record's own noise (:mod:`.noise_model`), and states what
remains (:mod:`.verdict`); :mod:`.pipeline` runs it, :mod:`.document` makes
the typed :class:`.diagnosis.Diagnosis` and :func:`.diagnosis.to_json` its
JSON; :mod:`.report` writes the Markdown report, :mod:`.export` the
extended sensor YAML, and :mod:`.command` runs the ``diagnose`` command. The records
with hidden effects that prove it come from :mod:`gyro_emulator.emulation.truth`.
"""

from gyro_emulator.analysis.diagnose.data import (load_measured, measured, MeasuredData,
                                                  write_measured_csv)
from gyro_emulator.analysis.diagnose.diagnosis import Diagnosis, to_json
from gyro_emulator.analysis.diagnose.generic import CANDIDATE_IDS, CATALOGUE, EFFECT_IDS
from gyro_emulator.analysis.diagnose.pipeline import diagnose

__all__ = ['CANDIDATE_IDS', 'CATALOGUE', 'diagnose', 'Diagnosis', 'EFFECT_IDS',
           'load_measured', 'measured', 'MeasuredData', 'to_json', 'write_measured_csv']
