"""STM32 peripheral models (RM0385, STM32F74x/F75x)."""
