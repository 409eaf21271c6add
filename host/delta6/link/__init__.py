"""The wire: protocol tables, COBS, CRC, decoders, wire scaling, the Device class and the log
format. Imports only delta6.core."""
