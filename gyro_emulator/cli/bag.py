"""
Inspect and repair rosbag2 MCAP bags.

  gyro-emulator bag info DIR          topics, counts, duration (like ros2 bag info)
  gyro-emulator bag repair DIR        recover a bag whose recorder was killed

``info`` reads every chunk once and reports what is damaged: corrupt
chunks with their message counts, messages the summary counts that no
intact chunk holds, a summary failing its CRC, repeated chunks.
``repair`` rewrites every .mcap file that lacks a trustworthy summary or
footer with all the messages it can recover (the original is kept as
``<file>.orig`` unless ``--no-backup``) and regenerates ``metadata.yaml``
when it is missing, malformed or disagrees with the files: a sound bag is
left byte for byte as it was. Both report what was recovered and what was lost.
"""

from gyro_emulator import outputs

HELP = 'inspect (info) or recover (repair) a rosbag2 MCAP bag'


def add_arguments(parser):
    """Register the ``bag`` actions."""
    sub = parser.add_subparsers(dest='action', metavar='ACTION')
    sub.required = True
    info = sub.add_parser('info', help='print topics, types, counts and duration')
    info.add_argument('bag', metavar='DIR', help='bag directory or .mcap file')
    repair = sub.add_parser('repair', help='recover a bag after SIGKILL or a crash')
    repair.add_argument('bag', metavar='DIR', help='bag directory or .mcap file')
    repair.add_argument('--out', metavar='DIR', default=None,
                        help='write the repaired bag here instead of in place')
    repair.add_argument('--no-backup', action='store_true',
                        help='do not keep the damaged originals as <file>.orig')


def run(args):
    """Print the bag summary or repair the bag."""
    # The bag modules (mcap, lz4, yaml: 40 ms) are imported here, not at the
    # top: `gyro-emulator --help` imports every command module.
    from gyro_emulator.recording import bag, files

    if args.action == 'info':
        reader = bag.BagReader(args.bag, tolerant=True)
        print(reader.info_text())
        shown = len(reader.problems)
        corrupt, lost = reader.verify()
        for note in reader.problems[shown:]:
            if not note.startswith(tuple(c['file'] + ': corrupt chunk' for c in corrupt)):
                print(f'Notice:           {note}')
        for chunk in corrupt:
            count = '?' if chunk['messages'] is None else chunk['messages']
            print(f'Corrupt chunk:    {chunk["file"]} byte {chunk["offset"]}, log time '
                  f'{chunk["start_ns"]}..{chunk["end_ns"]} ns, {count} messages '
                  f'({chunk["reason"]})')
        if lost:
            print(f'Messages lost:    {lost} of {reader.message_count} (counted, but in no '
                  'intact chunk)')
        disagree = files.metadata_disagreements(
            reader.metadata, reader.message_count,
            {name: topic.message_count for name, topic in reader.topics.items()},
            (reader.start_time_ns, reader.end_time_ns) if reader.message_count else None)
        for note in disagree:
            print(f'Notice:           {note}')
        if reader.problems or corrupt or lost or disagree:
            print(f'run: gyro-emulator bag repair {args.bag}')
        return 0
    # --out: not the bag, not inside it, not holding it; a non-empty one is refused by the repair
    outputs.check([outputs.directory('--out', args.out)], inputs=[args.bag], overwrite=True)
    report = bag.repair_bag(args.bag, out_dir=args.out, backup=not args.no_backup)
    print(report.describe())
    return 0
