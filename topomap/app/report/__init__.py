"""Reading runs back: a sweep's job folders, the summary of its jobs and the report (the Hydra
callback, and the command that rebuilds it)."""
