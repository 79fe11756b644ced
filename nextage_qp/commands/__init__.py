"""Subcommands of ``nextage-qp``: one module each, exposing ``register(subparsers)``."""
