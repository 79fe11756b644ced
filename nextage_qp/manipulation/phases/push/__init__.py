"""``push``: the phase (:mod:`.phase`), its spec (:mod:`.spec`), its approaches (:mod:`.approach`), contact."""
