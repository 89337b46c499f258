"""From a flight record to what the firmware reads: sensor models (`sensors`), resampling to the firmware's rate,
the integer input streams (`firmware_inputs`), the run CSV, and the generic-CSV export."""
