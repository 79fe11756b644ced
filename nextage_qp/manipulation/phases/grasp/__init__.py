"""``grasp``: the phase (:mod:`.phase`) and its spec (:mod:`.spec`)."""
