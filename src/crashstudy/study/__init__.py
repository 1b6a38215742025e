"""A study's variants: matrix, zip and sampled designs expanded into a numbered plan."""
