"""Record stage: experiment specs -> MuJoCo simulation -> one MCAP log per run."""
