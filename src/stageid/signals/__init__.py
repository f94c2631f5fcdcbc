"""stageid.signals"""
