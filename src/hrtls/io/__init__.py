"""Readers and writers: the session folder, user formats (``hrtls.io.readers``) and outputs."""
