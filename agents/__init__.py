"""Policies that map an observation to an action, and the code that evaluates them."""
