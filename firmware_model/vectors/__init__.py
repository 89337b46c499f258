"""vectors: golden vectors for microcontroller ports: the case matrix, computing cases, one module per output
format, the manifest. Imports runtime, spec, model, firmware and flights."""
