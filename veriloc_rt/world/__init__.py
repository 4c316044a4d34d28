"""Layer 2, world: where everything is. The scene (:mod:`.scene`: procedural urban canyon or an
external Mitsuba scene), the BS layout (:mod:`.topology`), the UE and adversary paths
(:mod:`.trajectory`) and their assembly into one :class:`~.geometry.Geometry` (:mod:`.geometry`)."""
