"""The built-in plugins: one folder per kind, one registered module per plugin (each with its template)."""
