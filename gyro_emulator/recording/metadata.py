"""rosbag2 bag metadata: QoS profiles, ``metadata.yaml``, topic and file info."""

from dataclasses import dataclass, field
import os

from gyro_emulator.resources import load_yaml_text
import yaml

#: rosbag2 metadata.yaml format version written (Jazzy).
ROSBAG2_VERSION = 9


ROS_DISTRO = 'jazzy'


METADATA_FILE = 'metadata.yaml'


def qos_profile(reliability='reliable', durability='volatile', history='keep_last',
                depth=10, liveliness='automatic'):
    """
    Return one offered QoS profile as a rosbag2 v9 metadata mapping.

    Parameters
    ----------
    reliability : str
        ``reliable`` or ``best_effort``.
    durability : str
        ``volatile`` or ``transient_local``.
    history : str
        ``keep_last`` or ``keep_all``.
    depth : int
        History depth.
    liveliness : str
        ``automatic`` or ``manual_by_topic``.

    """
    default = {'sec': 0, 'nsec': 0}      # 0 = unspecified: the rmw default (infinite)
    return {
        'history': history, 'depth': int(depth), 'reliability': reliability,
        'durability': durability, 'deadline': dict(default), 'lifespan': dict(default),
        'liveliness': liveliness, 'liveliness_lease_duration': dict(default),
        'avoid_ros_namespace_conventions': False,
    }


def dump_qos(profiles):
    return yaml.safe_dump(list(profiles), sort_keys=False).strip() if profiles else ''


def load_qos(text):
    """Return the QoS profiles a bag's ``offered_qos_profiles`` text holds ([] if unreadable)."""
    if not text:
        return []
    try:
        loaded = load_yaml_text(text, 'offered_qos_profiles', aliases=False)
    except ValueError:
        return []
    return loaded if isinstance(loaded, list) else []


@dataclass
class TopicInfo:
    """
    One topic of a bag.

    Attributes
    ----------
    name : str
        Topic name.
    type_name : str
        ``package/msg/Name``.
    message_count : int
        Messages on the topic.
    schema_text : str
        The ros2msg definition stored in the bag.
    serialization_format : str
        ``cdr``.
    qos_profiles : list of dict
        Offered QoS profiles recorded with the topic.
    type_description_hash : str
        RIHS01 hash ('' if unknown).

    """

    name: str
    type_name: str
    message_count: int = 0
    schema_text: str = ''
    serialization_format: str = 'cdr'
    qos_profiles: list = field(default_factory=list)
    type_description_hash: str = ''


@dataclass
class FileInfo:
    """Summary of one MCAP file of a bag."""

    path: str
    topics: dict
    message_count: int
    start_time_ns: int
    end_time_ns: int
    complete: bool = True
    custom_data: dict = field(default_factory=dict)
    scan: object = None
    summary: object = None


def topic_from(channel, schema, count):
    return TopicInfo(
        name=channel.topic,
        type_name=schema.name if schema is not None else '',
        message_count=int(count),
        schema_text=schema.data.decode('utf-8', 'replace') if schema is not None else '',
        serialization_format=channel.message_encoding,
        qos_profiles=load_qos(channel.metadata.get('offered_qos_profiles', '')),
        type_description_hash=channel.metadata.get('topic_type_hash', ''))


def topics_from(channels, schemas, counts):
    """
    Return ``{topic: TopicInfo}`` of a file's channels, their counts summed per topic.

    A topic may have several channels (rosbag2 and ``rosbags`` write one per
    publisher QoS or type hash): its count is that of all of them, as
    ``ros2 bag info`` gives it; the type and QoS are those of its first channel.

    Parameters
    ----------
    channels : dict
        Channel id -> ``mcap.records.Channel``.
    schemas : dict
        Schema id -> ``mcap.records.Schema``.
    counts : dict
        Channel id -> number of messages.

    """
    topics = {}
    for cid, channel in channels.items():
        info = topic_from(channel, schemas.get(channel.schema_id), counts.get(cid, 0))
        if channel.topic in topics:
            topics[channel.topic].message_count += info.message_count
        else:
            topics[channel.topic] = info
    return topics


def file_info_from_writer(writer):
    topics = {}
    for channel, schema, count in writer.topic_records():
        topics[channel.topic] = topic_from(channel, schema, count)
    start = writer.start_time_ns or 0
    return FileInfo(writer.path, topics, writer.message_count, start,
                    max(writer.end_time_ns, start))


def metadata_yaml(bag_dir, files, custom_data=None):
    """
    Return the rosbag2 ``metadata.yaml`` text (version 9) for ``files``.

    Parameters
    ----------
    bag_dir : str
        The bag directory (file paths are stored relative to it).
    files : list of FileInfo
        The MCAP files of the bag, in order.
    custom_data : dict, optional
        rosbag2 ``custom_data``.

    """
    counted = [f for f in files if f.message_count]
    start = min((f.start_time_ns for f in counted), default=0)
    end = max((f.end_time_ns for f in counted), default=start)
    topics = {}
    for info in files:
        for name, topic in info.topics.items():
            if name in topics:
                topics[name].message_count += topic.message_count
            else:
                topics[name] = TopicInfo(**{**topic.__dict__})
    data = {'rosbag2_bagfile_information': {
        'version': ROSBAG2_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': int(end - start)},
        'starting_time': {'nanoseconds_since_epoch': int(start)},
        'message_count': int(sum(f.message_count for f in files)),
        'topics_with_message_count': [{
            'topic_metadata': {
                'name': t.name, 'type': t.type_name,
                'serialization_format': t.serialization_format,
                'offered_qos_profiles': t.qos_profiles,
                'type_description_hash': t.type_description_hash},
            'message_count': int(t.message_count)} for t in topics.values()],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [os.path.relpath(f.path, bag_dir) for f in files],
        'files': [{
            'path': os.path.relpath(f.path, bag_dir),
            'starting_time': {'nanoseconds_since_epoch': int(f.start_time_ns)},
            'duration': {'nanoseconds': int(f.end_time_ns - f.start_time_ns)},
            'message_count': int(f.message_count)} for f in files],
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ROS_DISTRO,
    }}
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False)
