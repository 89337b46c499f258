"""Post-flight trajectory reconstruction (Chari's UKF with a multiplicative attitude error, then an unscented RTS
smoother): 6-DOF truth from RocketPy (:mod:`.truth`), sensor models (:mod:`.sensors`), the filter (:mod:`.ukf`),
simulated runs (:mod:`.simulated`), real logs (:mod:`.logs`), the reference apogee (:mod:`.apogee`).
docs/reconstruction.md."""
