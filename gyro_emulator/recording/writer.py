"""
A rosbag2 bag directory: one crash-safe MCAP file plus ``metadata.yaml``.

The MCAP file is written as it streams, not staged and renamed: a recording
must keep what it has if its process dies, so it is crash-safe by design
(chunks flushed as they close, :mod:`gyro_emulator.recording.mcap_writer`)
and a file cut short is made whole by ``gyro-emulator bag repair``. The
``metadata.yaml`` written at the end is one atomic write
(:func:`gyro_emulator.atomic.write_text`).
"""

import os

from gyro_emulator import atomic
from gyro_emulator.recording.mcap_writer import (DEFAULT_CHUNK_SIZE, DEFAULT_FLUSH_INTERVAL_S,
                                                 McapFileWriter)
from gyro_emulator.recording.metadata import (dump_qos, file_info_from_writer, METADATA_FILE,
                                              metadata_yaml, ROS_DISTRO)
from gyro_emulator.recording.msgdefs import message_definition, type_hash
import numpy as np


class BagWriter:
    """
    Write a rosbag2 bag directory (one MCAP file plus ``metadata.yaml``).

    Use as a context manager; leaving the block (also by an exception)
    finishes the bag. :meth:`finish` is safe to call twice.

    Parameters
    ----------
    path : str
        Bag directory to create. It must not exist or be empty, unless
        ``overwrite`` (which removes its .mcap files and metadata.yaml only).
    compression : str
        Chunk compression inside the MCAP file: ``zstd`` (default), ``lz4``
        or ``none``. rosbag2 reads all three.
    chunk_size : int
        Close a chunk at this many uncompressed bytes.
    flush_interval_s : float
        Upper bound on the wall-time age of unflushed messages, s: what a
        SIGKILL can lose (call :meth:`flush_if_due` from a timer when
        messages may stop arriving).
    custom_data : dict of str to str, optional
        rosbag2 ``custom_data``; also stored in the MCAP file at the start so
        :func:`repair_bag` restores it.
    overwrite : bool
        Replace an existing bag in ``path``.
    fsync : bool
        ``os.fsync`` on each flush.
    name : str, optional
        The bag's name, which names its MCAP file (``<name>_0.mcap``);
        default: the directory's. Give the final name when ``path`` is a
        staging temporary (:func:`gyro_emulator.atomic.staged`).

    Examples
    --------
    >>> with BagWriter('out/run1') as bag:                      # doctest: +SKIP
    ...     bag.add_topic('/imu/data_raw', 'sensor_msgs/msg/Imu')
    ...     bag.write('/imu/data_raw', payload, log_time_ns)

    """

    def __init__(self, path, compression='zstd', chunk_size=DEFAULT_CHUNK_SIZE,
                 flush_interval_s=DEFAULT_FLUSH_INTERVAL_S, custom_data=None,
                 overwrite=False, fsync=False, name=None):
        path = os.path.abspath(path)
        if os.path.exists(path) and not os.path.isdir(path):
            raise FileExistsError(f'bag path {path} exists and is not a directory')
        if os.path.isdir(path) and os.listdir(path):
            if not overwrite:
                raise FileExistsError(
                    f'bag directory {path} already exists and is not empty '
                    '(choose a new directory or pass overwrite=True)')
            for name in os.listdir(path):
                if name.endswith('.mcap') or name == METADATA_FILE:
                    os.remove(os.path.join(path, name))
        made = not os.path.isdir(path)
        os.makedirs(path, exist_ok=True)
        self.path = path
        self.custom_data = {str(k): str(v) for k, v in (custom_data or {}).items()}
        name = os.path.basename(str(name or path).rstrip(os.sep)) or 'bag'
        self.file_name = f'{name}_0.mcap'
        try:
            self._file = McapFileWriter(os.path.join(path, self.file_name), compression,
                                        chunk_size, flush_interval_s, fsync)
        except ValueError:
            if made:                    # a refused option leaves no empty bag directory
                os.rmdir(path)
            raise
        if self.custom_data:
            self._file.add_metadata('gyro_emulator', self.custom_data)
            self._file.flush()
        self._topics = {}
        self._schema_ids = {}
        self._qos = {}
        self._hash = {}

    # -- topics ---------------------------------------------------------------
    def add_topic(self, topic, type_name, schema_text=None, qos_profiles=(),
                  type_description_hash=None):
        """
        Register a topic once; return its channel id.

        Parameters
        ----------
        topic : str
            Topic name (absolute, e.g. ``/imu/data_raw``).
        type_name : str
            ``package/msg/Name``.
        schema_text : str, optional
            ros2msg definition; read from the installed .msg files if omitted.
        qos_profiles : sequence of dict
            Offered QoS profiles (:func:`qos_profile` mappings).
        type_description_hash : str, optional
            RIHS01 hash; read from the installed type description if omitted.

        Raises
        ------
        ValueError
            If the topic was registered with another type.

        """
        if topic in self._topics:
            known = self._file.topic_records()[self._topics[topic] - 1][1].name
            if known != type_name:
                raise ValueError(
                    f'topic {topic} is already recorded as {known}, not {type_name}')
            return self._topics[topic]
        if type_name not in self._schema_ids:
            text = message_definition(type_name) if schema_text is None else schema_text
            self._schema_ids[type_name] = self._file.add_schema(type_name, text)
        digest = type_hash(type_name) if type_description_hash is None \
            else type_description_hash
        profiles = [dict(p) for p in qos_profiles]
        cid = self._file.add_channel(topic, self._schema_ids[type_name], {
            'offered_qos_profiles': dump_qos(profiles), 'topic_type_hash': digest})
        self._topics[topic] = cid
        return cid

    @property
    def topics(self):
        """Return {topic: channel id} of the registered topics."""
        return dict(self._topics)

    def channel_id(self, topic):
        """Return the channel id of a registered topic (ValueError otherwise)."""
        try:
            return self._topics[topic]
        except KeyError:
            raise ValueError(f'topic {topic} was not added to the bag '
                             '(call add_topic first)') from None

    # -- messages -------------------------------------------------------------
    def write(self, topic, data, log_time_ns, publish_time_ns=None, sequence=0):
        """
        Write one serialised message.

        Parameters
        ----------
        topic : str or int
            Topic name or the channel id :meth:`add_topic` returned.
        data : bytes
            CDR-serialised message (as rclpy ``serialize_message`` returns).
        log_time_ns : int
            Receive time, ns.
        publish_time_ns : int, optional
            Send time, ns (default: ``log_time_ns``).
        sequence : int
            Publisher sequence number, if known.

        """
        cid = topic if isinstance(topic, int) else self.channel_id(topic)
        self._file.write(cid, data, log_time_ns, publish_time_ns, sequence)

    def write_batches(self, batches):
        """
        Write several topics' messages interleaved in log-time order.

        Parameters
        ----------
        batches : iterable of (topic, payloads, log_times_ns)
            Each batch is a topic, a sequence of serialised messages and
            their integer-nanosecond log times. Ties keep batch order.

        """
        ids, datas, times = [], [], []
        for topic, payloads, log_times in batches:
            log_times = np.asarray(log_times, dtype=np.int64).reshape(-1)
            if len(payloads) != len(log_times):
                raise ValueError(f'{topic}: {len(payloads)} payloads but '
                                 f'{len(log_times)} log times')
            cid = topic if isinstance(topic, int) else self.channel_id(topic)
            ids.append(np.full(len(log_times), cid, dtype=np.int64))
            datas.extend(payloads)
            times.append(log_times)
        if not datas:
            return
        all_times = np.concatenate(times)
        all_ids = np.concatenate(ids)
        order = np.argsort(all_times, kind='stable')
        write = self._file.write
        for i, cid, t in zip(order.tolist(), all_ids[order].tolist(),
                             all_times[order].tolist()):
            write(cid, datas[i], t)

    def flush_if_due(self):
        """Flush the open chunk if older than ``flush_interval_s`` (call from a timer)."""
        self._file.flush_if_due()

    def flush(self):
        """Close and flush the open chunk now."""
        self._file.flush()

    @property
    def message_count(self):
        """Return the number of messages written."""
        return self._file.message_count

    def set_custom_data(self, key, value):
        """Set one rosbag2 ``custom_data`` entry (written by :meth:`finish`)."""
        self.custom_data[str(key)] = str(value)

    # -- closing ----------------------------------------------------------------
    def finish(self):
        """Finish the MCAP file and write ``metadata.yaml``. Safe to call twice."""
        if self._file.finished:
            return
        info = file_info_from_writer(self._file)
        text = metadata_yaml(self.path, [info], self.custom_data)
        try:
            self._file.add_metadata('rosbag2', {
                'serialized_metadata': text, 'ROS_DISTRO': ROS_DISTRO})
        finally:
            self._file.finish()
        atomic.write_text(os.path.join(self.path, METADATA_FILE), text)

    def __enter__(self):
        """Return the writer."""
        return self

    def __exit__(self, *exc):
        """Finish the bag, also when the block raised."""
        self.finish()
        return False
