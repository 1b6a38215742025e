"""Exchange with the crash world's formats: ISO-MME test data (:mod:`.isomme`, :mod:`.testcurve`) and LS-DYNA
keyword decks (:mod:`.dyna_export`, :mod:`.dyna_import`)."""
