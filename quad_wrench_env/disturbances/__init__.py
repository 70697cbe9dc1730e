"""Disturbances: winds, jets, gusts and point loads, each a component with its compiled kernel."""
