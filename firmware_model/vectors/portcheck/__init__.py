"""Check a team's own C port against the bit-exact integer model (docs/port-check.md, ``fwemu check-port``)."""
