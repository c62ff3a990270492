"""The package version (also written into every EXR as ``mi_npr/version``)."""

__version__ = "0.1.0"
