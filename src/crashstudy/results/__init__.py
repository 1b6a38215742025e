"""Result folders: results.nc written chunk by chunk, summaries, checksums, reading back."""
