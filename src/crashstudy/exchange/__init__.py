"""Exchange with the crash world's formats: ISO-MME test data (:mod:`.isomme`, :mod:`.testcurve`)."""
