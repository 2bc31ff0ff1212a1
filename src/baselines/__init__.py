"""Experiments and the ``agrinav`` command line: scenarios now; training and benchmarks later."""
