"""From a flight record to what the firmware reads: sensor models (`sensors`), resampling to the firmware's rate,
the integer input streams (`firmware_inputs`) and the run CSV (`runcsv`). The generic CSV is written
beside its reader, :mod:`firmware_model.flights.readers.generic`."""
