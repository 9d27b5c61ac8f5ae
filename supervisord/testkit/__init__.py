"""Tools that ship with the package so integrators can test their robot code without hardware."""
