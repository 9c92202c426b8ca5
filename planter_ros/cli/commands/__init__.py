"""The work of each `planter` sub-command, `run(args) -> int`, one module per sub-command, its
imports at its top; `cli.main` imports only the one asked for, after its arguments parsed."""
