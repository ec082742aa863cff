"""Peripheral models, one module per peripheral type, per vendor (stm32/, cortexm/, ...)."""
