"""The pipeline's vocabulary (ground floor): codes and the material table, read by schema/, arrays/ and kernel/."""
