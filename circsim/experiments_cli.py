"""Registry of the experiment subcommands (``circsim offline``, ``circsim sweep``).

Each entry is a function ``register(subparsers)`` that adds one subparser and sets its handler with
``parser.set_defaults(func=handler)``; the handler takes the parsed args and returns an exit code.
"""

from __future__ import annotations

REGISTER: list = []
