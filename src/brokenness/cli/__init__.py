"""The ``brokenness`` command-line interface (see :func:`brokenness.cli.main.main`)."""
