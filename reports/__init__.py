"""JUnit XML, JSON and HTML report renderers."""
