"""The built-in `playscope` subcommands, one module each with add_parser(subparsers)."""
