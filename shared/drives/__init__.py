"""The PRBT's drives on CAN: opening the bus, CiA 402, PDO layouts, the drive facts and EDS both ends
read, and the robot driver's pure core."""
