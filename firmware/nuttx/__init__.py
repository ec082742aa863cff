"""NuttX pieces of the OpenRover robot controller (LPC4337), written like their C originals."""
