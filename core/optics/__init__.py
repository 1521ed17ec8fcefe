"""Physics that several techniques share and none owns: lights at a point, the medium light
crosses from behind, the surface a pixel covers, the profiles and the energy model."""
