"""What a log itself says happened: liftoff, ground pressure and the reference apogee (`apogee_reference`), and
the pyro charges seen in it (`charge`)."""
