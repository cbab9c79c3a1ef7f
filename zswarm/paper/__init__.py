"""The paper's mathematics (Kim, Wang & Shin 2006): potentials, forces, parameters, neighbour geometry."""
