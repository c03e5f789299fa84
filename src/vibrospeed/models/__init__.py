"""What the systems are: parameters, transition and measurement functions. No inference here."""
