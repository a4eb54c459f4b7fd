"""
rosbag2-compatible MCAP bags: the public names in one place.

A bag is a directory holding ``<name>_0.mcap`` and ``metadata.yaml``, the
layout ``ros2 bag record -s mcap`` produces (rosbag2 metadata version 9).
The implementation lives in small modules beside this one:

- :mod:`.msgdefs` -- message definitions (ros2msg schemas) and type hashes;
- :mod:`.metadata` -- QoS profiles, ``metadata.yaml``, topic and file info;
- :mod:`.mcap_writer` -- the crash-safe MCAP file writer;
- :mod:`.writer` -- :class:`BagWriter`, a bag directory;
- :mod:`.files` -- ``metadata.yaml`` read as untrusted input, the files of a bag;
- :mod:`.reader` -- :class:`BagReader`, messages and decoded columns;
- :mod:`.scan` -- the tolerant record scanner :func:`scan_mcap` (summary CRC,
  resync past damage, repeated chunks dropped);
- :mod:`.repair` -- :func:`repair_bag`.

All times are integer nanoseconds (``log_time`` is the receive time,
``publish_time`` the send time, both since the Unix epoch or the sim clock).
"""

from gyro_emulator.recording.mcap_writer import (COMPRESSIONS, DEFAULT_CHUNK_SIZE,
                                                 DEFAULT_FLUSH_INTERVAL_S, MAX_FLUSH_INTERVAL_S,
                                                 McapFileWriter)
from gyro_emulator.recording.metadata import (FileInfo, METADATA_FILE, metadata_yaml,
                                              qos_profile, ROS_DISTRO, ROSBAG2_VERSION,
                                              TopicInfo)
from gyro_emulator.recording.msgdefs import message_definition, type_hash
from gyro_emulator.recording.reader import BagMessage, BagReader, TopicArrays
from gyro_emulator.recording.repair import repair_bag, RepairReport
from gyro_emulator.recording.scan import scan_mcap, ScanReport
from gyro_emulator.recording.writer import BagWriter

__all__ = [
    'BagMessage', 'BagReader', 'BagWriter', 'COMPRESSIONS', 'DEFAULT_CHUNK_SIZE',
    'DEFAULT_FLUSH_INTERVAL_S', 'FileInfo', 'MAX_FLUSH_INTERVAL_S', 'McapFileWriter',
    'message_definition', 'METADATA_FILE', 'metadata_yaml', 'qos_profile', 'repair_bag',
    'RepairReport', 'ROS_DISTRO', 'ROSBAG2_VERSION', 'scan_mcap', 'ScanReport', 'TopicArrays',
    'TopicInfo', 'type_hash']
