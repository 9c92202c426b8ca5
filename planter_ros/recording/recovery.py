"""Reading what is intact in an MCAP file that cannot be read the fast way: a file without its
summary (a killed recorder) or with a damaged record. Records are read in file order with their
CRCs checked, up to the first damaged or missing one; what came before it is kept and the loss
is reported as a warning."""


def one_line(exc):
    """`Type: first line of the message` of an exception, for a warning."""
    text = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {text[0]}' if text else type(exc).__name__


def read_records(file, warnings):
    """Stream `file`: (channels {id: (topic, schema name)}, messages [(channel id, log time ns,
    CDR bytes)], metadata {record name: {key: value}}). Appends a warning if it stopped early."""
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader
    schemas, channels, messages, metadata = {}, {}, [], {}
    try:
        with open(file, 'rb') as f:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ''))
                elif isinstance(record, Message):
                    messages.append((record.channel_id, record.log_time, record.data))
                elif isinstance(record, Metadata):
                    metadata[record.name] = dict(record.metadata)
    except Exception as exc:     # truncated or corrupt: keep what was read before it
        warnings.append(f'{file}: stopped at a damaged record ({one_line(exc)}); '
                        f'{len(messages)} messages recovered')
    return channels, messages, metadata
