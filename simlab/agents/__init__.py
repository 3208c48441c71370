"""Agent library shared by the physics half and Visit-the-lab (SPEC C)."""
