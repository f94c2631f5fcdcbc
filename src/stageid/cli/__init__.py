"""stageid.cli"""
