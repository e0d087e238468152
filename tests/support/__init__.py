"""Support code for the tests: paper fixtures, synthetic scenes."""
