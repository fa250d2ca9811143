"""railtwin benchmarks: ``make bench`` runs ``benchmarks.run_all``."""
