"""The runner (the one module that knows the whole pipeline) and its execution backends."""
