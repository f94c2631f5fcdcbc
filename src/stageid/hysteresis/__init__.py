"""stageid.hysteresis"""
