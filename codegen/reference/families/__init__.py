"""One reference module per family, named like the symbolic one (codegen/families/observers/
and controllers/): numpy + pinocchio only."""
