"""stageid.models"""
