"""The `langtraj` command: one module per verb, dispatched by `langtraj.cli.main`. See README.md."""
