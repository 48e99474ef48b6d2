"""FE×DEM: a DEM cell at every quadrature point of the FEM solver."""
