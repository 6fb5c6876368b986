"""On the wire: the messages, the conversion between them and the cores' types, and the Zenoh key space."""
