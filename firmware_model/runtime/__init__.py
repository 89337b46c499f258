"""runtime: what every command needs and nothing domain-specific: atomic outputs, folder locks, interrupts,
progress, the process pool, hashing, Markdown tables, the disk cache, errors. Imports nothing of firmware_model."""
