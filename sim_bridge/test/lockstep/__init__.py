"""Tests of the lockstep runtime; a package so that its conftest is not a bare `conftest`."""
