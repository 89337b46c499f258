"""cli: the ``fwemu`` command, one module per command. Nothing imports it."""
