"""The simulators: the 1-DOF point-mass flight (`sim1dof`), RocketPy 6-DOF (`rocketpy_sim`), motor curves
(`motors`, `data/`), the named scenarios, the pressure-port errors, and the cross-check of the two simulators.
They import the record type and nothing of the evaluation."""
