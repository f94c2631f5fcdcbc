"""Placeholder: the table of modules follows in the next commit."""
