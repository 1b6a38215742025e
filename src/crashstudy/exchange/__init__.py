"""Exchange with the crash world's formats: LS-DYNA keyword decks (:mod:`.dyna_export`, :mod:`.dyna_import`)."""
