"""Reading blasthole tables, writing exports and project files, atomic saves."""
