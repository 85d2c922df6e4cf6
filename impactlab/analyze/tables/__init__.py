"""Tables over runs, as written: every run's frames combined, the runs table (`summary`),
sweep studies, readable run labels and the energy table's decimation."""
