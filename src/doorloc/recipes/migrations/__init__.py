"""Alembic migrations of the recipe database (run by doorloc.recipes.store.migrate; no alembic.ini needed)."""
