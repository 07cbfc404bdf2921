"""The Fresnel slot: how much the surface reflects, by the angle of incidence (selector
``render.fresnel``). Shared here: the reflectance of a complex index (:mod:`.reflectance`)."""
