"""The section and its mesh: sizes from the case (:mod:`.sizing`), the gmsh model of ground and
lining with the interface, layer lines and joint cuts (:mod:`.mesh`)."""
