"""fuzzyctl end of the serial link (docs/protocol.md): schema-driven codec, framing, transport, device operations."""
