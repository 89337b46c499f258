"""Study scripts (run with `python -m` or from bench/): they import the library, nothing imports them."""
