from topomap import schema  # noqa: F401  (registers the structured-config schemas)
