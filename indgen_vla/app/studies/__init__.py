"""Commands over whole evaluations: size a protocol before it runs (``budget``, with its wall-time model
``wall_time``), evaluate every checkpoint of a training (``series``), and join a protocol's shards (``merge``)."""
