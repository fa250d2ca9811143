"""Validation runs that are too long for the test suite (``make validate``)."""
