"""Zenoh transport made safe: the one place sessions are opened, the cell's PKI for mutual TLS,
and the router's access control."""
