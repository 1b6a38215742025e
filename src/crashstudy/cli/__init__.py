"""The command line: parses arguments, prints, sets exit codes."""
