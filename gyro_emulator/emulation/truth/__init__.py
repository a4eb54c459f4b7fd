"""
The truth generator: synthetic measured records with hidden effects.

:mod:`.generator` runs a part (:class:`gyro_emulator.sensor.model.GyroModel`)
through a sampled test profile (:func:`.drawn.draw_profile`)
with the effects of :mod:`.effects` planted in it, and returns the record
beside the truth it hides; ``diagnose`` is proved on such records.
"""
