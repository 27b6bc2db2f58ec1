"""camkit's benchmarks: ``python -m benchmarks`` runs them all against their peers."""
