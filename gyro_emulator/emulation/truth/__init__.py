"""
The truth generator: synthetic measured records with hidden effects.

:mod:`.generator` runs a part (:class:`gyro_emulator.sensor.model.GyroModel`)
through a sampled test profile (:func:`.drawn.draw_profile`)
with the effects of :mod:`.effects` planted in it, and returns the record
beside the truth it hides; ``diagnose`` is proved on such records.
"""

#: The test profiles the generator samples (:func:`.drawn.draw_profile`); here,
#: without the sensor model's imports, for the command line's choices.
SAMPLED_PROFILES = ('lab', 'paper', 'thermal_ramp', 'thermal_cycle', 'static')
