"""The mismatch tool: locate, name and model physics a simulation leaves out."""
