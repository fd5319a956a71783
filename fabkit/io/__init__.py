"""Readers and writers, with typed entry points (`load_obj`, `load_fold`, ...)."""
