"""Library experiments behind the CLI's reach and step-response commands."""
