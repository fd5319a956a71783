"""One module per `fabkit` subcommand (see fabkit/cli.py for the contract)."""
