"""Basics every layer uses: errors, settings, warnings, version, progress, memory limits, the camera projection, the thread pool."""
