"""What can be generated: observer families (observers/, one per file), control laws
(controllers/) and the gain designs they use (design/, one rule per file)."""
